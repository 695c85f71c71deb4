"""The REST API against a live run: real Zenoh sessions on loopback, the app's lifespan (``with TestClient``).

The plant runs in real time at ×1 (a long fault-free turbine scenario); the bad-input tests come first, while
the supervisor warms up, then a speed-sensor fault is injected and its detection must show in the status route
within 0.5 s. Every refusal is also checked on the plant's side: its fault list is unchanged and no fault was
injected.
"""

from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from api.settings import ApiSettings
from tests.live.helpers import LiveNodes, router, scenario, wait_for

TOKEN = "test-token-123"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
LONG_TURBINE = """
name = "api-test"
duration_s = 900.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0]]
"""
GOOD = {"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 0.0, "end_s": 800.0}


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("api") / "run"
    with router() as endpoint, LiveNodes(endpoint, scenario(LONG_TURBINE), run_dir, mode="realtime", speed=1.0) as n:
        # the limits on clients have their own tests (tests/security/test_api.py): room for this file's requests
        settings = ApiSettings(
            connect=endpoint, api_token=TOKEN, run_dir=None, api_rate_per_s=1000.0, api_rate_burst=1000
        )
        with TestClient(create_app(settings)) as client:
            assert wait_for(lambda: client.get("/health").json()["plant"], 30)
            yield client, n


@pytest.fixture
def client(live):
    return live[0]


def plant_faults(client) -> list:
    return [f["label"] for group in ("active", "pending", "past") for f in client.get("/faults").json()[group]]


def injected_events(client) -> int:
    return len(client.get("/events", params={"type": "fault_injected"}).json()["events"])


def refused_without_effect(client, response, status, field=None):
    """``response`` has ``status``, names ``field`` if given, and nothing reached the plant."""
    assert response.status_code == status, response.text
    if field is not None:
        detail = response.json()["detail"]
        assert isinstance(detail, list) and any(field in map(str, item["loc"]) for item in detail), detail
        assert any(item["msg"] for item in detail)


def test_health_and_run_status(client):
    health = client.get("/health").json()
    assert health["status"] == "ok" and health["zenoh"] == "open" and health["plant"]
    assert wait_for(lambda: client.get("/health").json()["supervisor"], 30)
    run = client.get("/run").json()
    assert run["scenario"] == "api-test" and run["mode"] == "realtime" and run["speed"] == 1.0
    assert run["kind"] == "turbine" and run["turbines"] == [1] and run["t"] >= 0.0
    assert {"overruns", "real_time_factor", "latency", "latency_recent"} <= set(run)


@pytest.mark.parametrize(
    "body, field, text",
    [
        (GOOD | {"turbine": 5}, "turbine", "turbine 5 does not exist"),
        (GOOD | {"target": "omega_x_m9"}, "target", "omega_x_m9"),
        (GOOD | {"value": 1000.0}, "value", "outside the physical range"),
        (GOOD | {"start_s": 50.0, "end_s": 40.0}, "end_s", "must be after start_s"),
        (GOOD | {"value": "fast"}, "value", None),
        (GOOD | {"turbine": "one"}, "turbine", None),
        (GOOD | {"colour": "red"}, "colour", None),
        ({k: v for k, v in GOOD.items() if k != "kind"}, "kind", None),
        (GOOD | {"kind": "explode"}, "kind", None),
        (GOOD | {"kind": "gain", "value": None}, "value", "needs a value"),
        (GOOD | {"start_s": 1e6, "end_s": 2e6}, "start_s", "after the run ends"),
    ],
    ids=[
        "unknown-turbine",
        "unknown-channel",
        "out-of-range",
        "end-before-start",
        "value-type",
        "turbine-type",
        "unknown-key",
        "missing-kind",
        "unknown-kind",
        "missing-value",
        "after-the-run",
    ],
)
def test_bad_injections_are_refused_naming_the_field_and_never_reach_the_plant(client, body, field, text):
    before, events = plant_faults(client), injected_events(client)
    response = client.post("/faults", json=body, headers=AUTH)
    refused_without_effect(client, response, 422, field)
    if text:
        assert text in response.text
    assert plant_faults(client) == before and injected_events(client) == events


@pytest.mark.parametrize(
    "payload",
    [
        b"{not json",
        b'{"value": NaN, "target": "omega_g_m2", "kind": "fixed", "start_s": 0}',
        b"[1, 2]",
        b"",
        b'"\xff"',  # not UTF-8
        b'{"target": "\\udcff", "kind": "fixed", "value": 1, "start_s": 0}',  # a lone surrogate, echoed back
    ],
    ids=["not-json", "nan", "array", "empty", "not-utf8", "lone-surrogate"],
)
def test_malformed_bodies_get_422(client, payload):
    before = plant_faults(client)
    response = client.post("/faults", content=payload, headers=AUTH | {"content-type": "application/json"})
    refused_without_effect(client, response, 422)
    assert plant_faults(client) == before


@pytest.mark.parametrize(
    "headers",
    [{}, {"Authorization": "Bearer wrong"}, {"Authorization": TOKEN}, {"Authorization": f"Basic {TOKEN}"}],
    ids=["none", "wrong", "no-scheme", "basic"],
)
def test_mutations_without_the_token_get_401(client, headers):
    before = plant_faults(client)
    for response in (
        client.post("/faults", json=GOOD, headers=headers),
        client.post("/faults", content=b"{bad", headers=headers),  # auth is checked first
        client.delete("/faults/anything", headers=headers),
    ):
        assert response.status_code == 401 and response.headers["www-authenticate"] == "Bearer"
    assert plant_faults(client) == before


def test_unknown_names_in_paths_get_404(client):
    response = client.delete("/faults/no-such-fault", headers=AUTH)
    assert response.status_code == 404 and "no-such-fault" in response.text
    assert wait_for(lambda: client.get("/health").json()["supervisor"], 30)
    response = client.get("/supervisor/status/7")
    assert response.status_code == 404 and "turbine 7" in response.text
    assert client.get("/supervisor/status/0").status_code == 422


def test_event_cursor_validation(client):
    assert client.get("/events", params={"since": -1}).status_code == 422
    assert client.get("/events", params={"limit": 0}).status_code == 422
    assert client.get("/events", params={"type": "nonsense"}).status_code == 422


def test_injection_reaches_the_plant_within_a_tick_and_is_detected_within_half_a_second(client, live):
    nodes = live[1]
    assert wait_for(lambda: client.get("/run").json()["t"] > 11.0, 40), "supervisor warm-up"
    assert client.get("/supervisor/status/1").json()["flagged"] == []
    sent = time.monotonic()
    response = client.post("/faults", json=GOOD | {"name": "api fault"}, headers=AUTH)
    posted = time.monotonic()
    assert response.status_code == 201, response.text
    applied_t = response.json()["t"]
    assert response.json()["fault"]["state"] == "active" and response.json()["fault"]["start_s"] == applied_t
    detected = wait_for(lambda: "omega_g_m2" in client.get("/supervisor/status/1").json()["flagged"], 0.5, 0.005)
    latency = time.monotonic() - sent
    assert detected, "the detection did not show in the status route within 0.5 s"
    print(f"\ninjection → detection in the status route: {1e3 * latency:.0f} ms (POST {1e3 * (posted - sent):.0f} ms)")
    status = client.get("/supervisor/status/1").json()
    assert (
        status["detected"]
        and status["observer"]
        and status["margins"]
        and status["estimates"]["valid"] in (True, False)
    )
    # the plant applied it at the tick the command arrived: the injection event carries that tick's time
    assert wait_for(lambda: injected_events(client) == 1, 2)
    event = client.get("/events", params={"type": "fault_injected"}).json()["events"][0]
    assert event["t"] == applied_t and event["detail"]["label"] == "api fault"
    assert nodes.plant.book.find("api fault").state(nodes.plant.plant.t) == "active"
    conflict = client.post("/faults", json=GOOD | {"name": "api fault"}, headers=AUTH)
    assert conflict.status_code == 409
    cleared = client.delete("/faults/api fault", headers=AUTH)
    assert cleared.status_code == 200 and cleared.json()["fault"]["state"] == "ended"
    assert wait_for(lambda: "omega_g_m2" not in client.get("/supervisor/status/1").json()["flagged"], 5)
    listing = client.get("/faults").json()
    assert [f["label"] for f in listing["past"]] == ["api fault"] and listing["active"] == []
    assert client.delete("/faults/api fault", headers=AUTH).status_code == 409


def test_events_page_with_a_cursor(client):
    first = client.get("/events", params={"limit": 2}).json()
    assert len(first["events"]) == 2 and first["next"] == first["events"][-1]["seq"] + 1
    rest = client.get("/events", params={"since": first["next"]}).json()
    assert all(e["seq"] >= first["next"] for e in rest["events"])
    types = {e["type"] for e in client.get("/events").json()["events"]}
    assert {"fault_injected", "detection", "fault_cleared", "liveliness"} <= types


def test_metrics_in_prometheus_text(client):
    assert client.post("/faults", json=GOOD).status_code == 401
    assert client.get("/faults/some-label").status_code == 405  # a path with a parameter: counted by template
    response = client.get("/metrics")
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/plain")
    text = response.text
    assert 'windwarden_up{process="plant"} 1' in text and "windwarden_overruns_total" in text
    assert 'windwarden_api_requests_total{method="POST",route="/faults",status="401"}' in text
    assert 'windwarden_loop_latency_seconds{quantile="0.99"}' in text
    assert 'route="/faults/{label}",status="405"' in text and "some-label" not in text
    families = [line.split()[2] for line in text.splitlines() if line.startswith("# TYPE")]
    assert len(families) == len(set(families)), "each metric family is declared once"
