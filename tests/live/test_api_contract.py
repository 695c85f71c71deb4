"""The OpenAPI schema against behaviour: each route can return every status code it documents, and returns none
it does not.

The app runs under uvicorn on loopback with a stand-in for its Zenoh bridge, so each upstream failure (plant or
supervisor gone, an error reply, an unusable reply, no answer in time) can be produced on demand. Each mutating
request comes from its own loopback address (its own rate-limit bucket) unless the case is the rate limit itself.
The schemathesis run (``test_api_schema.py``) checks, against a live run, that random requests get documented codes.
"""

from __future__ import annotations

import itertools
import socket
import threading
import time
from collections.abc import Callable, Iterator
from types import SimpleNamespace
from typing import Any

import httpx
import pytest

from api.bridge import EventStore
from api.main import create_app
from api.settings import ApiSettings
from tests.live.api_server import serve
from windwarden.live.transport import QueryFailedError
from wwcore.keys import Process
from wwcore.wire import DropCounter

TOKEN = "contract-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
GOOD = {"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 0.0, "end_s": 80.0, "name": "x1"}
LATENCY = {"count": 1, "p50_ms": 1.0, "p99_ms": 2.0, "max_ms": 3.0}
PLANT_STATUS = {
    "run_id": "r",
    "scenario": "s",
    "kind": "turbine",
    "turbines": [1],
    "mode": "realtime",
    "speed": 1.0,
    "state": "running",
    "t": 1.0,
    "tick": 100,
    "duration_s": 100.0,
    "real_time_factor": 1.0,
    "ticks": 100,
    "overruns": 0,
    "overrun_pct": 0.0,
    "latency": LATENCY,
    "latency_recent": LATENCY,
    "supervisor_alive": True,
    "refs_fresh": True,
    "refs_received": 100,
}
SUPERVISOR_STATUS = {
    "run_id": "r",
    "kind": "turbine",
    "tick": 100,
    "t": 1.0,
    "ready": True,
    "stream_fresh": True,
    "plant_alive": True,
    "frames": 100,
    "turbines": [{"turbine": 1, "flagged": [], "observer": "a", "margins": {}}],
}


def listed(label: str, state: str) -> dict[str, Any]:
    fault = {"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 0.0, "turbine": 1, "name": label}
    return {"label": label, "state": state, "source": "api", "start_s": 0.0, "end_s": None, "cleared_at_s": None,
            "fault": fault}  # fmt: skip


class StandInBridge:
    """What ``api.bridge.Bridge`` offers the routes, with the plant and supervisor played by the test."""

    def __init__(self, settings: ApiSettings):
        self.session = SimpleNamespace(is_closed=lambda: False)
        self.drops = DropCounter()
        self.events = EventStore(1000)
        self.started = time.time()
        self.reset()

    def reset(self) -> None:
        self.plant = self.supervisor = True
        self.failure: QueryFailedError | None = None  # every query raises it
        self.unusable = False  # every query answers a body without the expected fields
        self.listing = [listed("known", "active"), listed("over", "ended")]
        self.gate: threading.Event | None = None
        self.entered = threading.Event()

    def close(self) -> None:
        pass

    def alive(self, process: str) -> bool:
        return {Process.PLANT: self.plant, Process.SUPERVISOR: self.supervisor}.get(process, True)

    def _answer(self, reply: dict[str, Any]) -> dict[str, Any]:
        if self.gate is not None:
            self.entered.set()
            assert self.gate.wait(30)
        if self.failure is not None:
            raise self.failure
        return {"unexpected": [1]} if self.unusable else reply

    def plant_status(self, timeout: float | None = None) -> dict[str, Any]:
        return self._answer(PLANT_STATUS)

    def run_info(self) -> dict[str, Any]:
        return self._answer({"kind": "turbine", "turbines": [1], "duration_s": 100.0})

    def supervisor_status(self, timeout: float | None = None) -> dict[str, Any]:
        return self._answer(SUPERVISOR_STATUS)

    def faults(self, body: dict[str, Any]) -> dict[str, Any]:
        op = body["op"]
        if op == "list":
            return self._answer({"ok": True, "t": 1.0, "faults": self.listing})
        if self._answer({}) != {}:
            return {"unexpected": [1]}
        if op == "inject":
            label = body["fault"]["name"]
            if any(f["label"] == label for f in self.listing):
                problems = [["name", f"a fault labelled {label!r} exists already"]]
                raise QueryFailedError("exists", 409, {"error": "exists", "status": 409, "problems": problems})
            return {"ok": True, "t": 1.0, "fault": listed(label, "active")}
        found = [f for f in self.listing if f["label"] == body["label"]]
        if not found:
            raise QueryFailedError("none", 404, {"error": "none", "status": 404, "problems": [["label", "none"]]})
        if found[0]["state"] != "active":
            raise QueryFailedError("over", 409, {"error": "over", "status": 409, "problems": [["label", "over"]]})
        return {"ok": True, "t": 1.0, "fault": {**found[0], "state": "ended"}}


class Harness:
    def __init__(self, base: str, bridge: StandInBridge):
        self.base = base
        self.bridge = bridge
        self._addresses = (f"127.0.{i // 250}.{2 + i % 250}" for i in itertools.count(250))

    def client(self, address: str | None = None) -> httpx.Client:
        """A client from its own loopback address (a fresh rate-limit bucket) unless one is given."""
        # plain HTTP on loopback: verify=False spares building a TLS context (0.1 s) per client
        transport = httpx.HTTPTransport(local_address=address or next(self._addresses), verify=False)
        return httpx.Client(base_url=self.base, transport=transport, timeout=30)

    def send(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        with self.client() as c:
            return c.request(method, path, **kwargs)

    def slow_body(self, method: str, path: str) -> httpx.Response:
        """A request that promises 10 body bytes and sends 2, from its own address, read off the socket."""
        host, port = self.base.removeprefix("http://").split(":")
        head = f"{method} {path} HTTP/1.1\r\nHost: a\r\nAuthorization: Bearer {TOKEN}\r\nContent-Length: 10\r\n\r\n{{}}"
        with socket.create_connection((host, int(port)), timeout=30, source_address=(next(self._addresses), 0)) as s:
            s.sendall(head.encode())
            answer = b""
            while chunk := s.recv(65536):
                answer += chunk
        head_text, _, body = answer.partition(b"\r\n\r\n")
        lines = head_text.decode("latin-1").split("\r\n")
        headers = [tuple(part.strip() for part in line.split(":", 1)) for line in lines[1:]]
        return httpx.Response(int(lines[0].split()[1]), headers=headers, content=body)


@pytest.fixture(scope="module")
def harness() -> Iterator[Harness]:
    bridges: list[StandInBridge] = []

    def factory(settings: ApiSettings) -> StandInBridge:
        bridges.append(StandInBridge(settings))
        return bridges[-1]

    settings = ApiSettings(
        api_token=TOKEN,
        api_rate_per_s=0.01,
        api_rate_burst=3,
        api_max_concurrent=1,
        api_max_faults_per_turbine=2,
        api_body_timeout_s=0.3,
    )
    with serve(create_app(settings, bridge_factory=factory)) as base:
        yield Harness(base, bridges[0])


@pytest.fixture
def h(harness: Harness) -> Iterator[Harness]:
    harness.bridge.reset()
    yield harness
    harness.bridge.reset()


def fail(h: Harness, **state: Any) -> None:
    for key, value in state.items():
        setattr(h.bridge, key, value)


NO_ANSWER = QueryFailedError("no answer within 2 s", 503)  # the transport's own: no body
ERROR_REPLY = QueryFailedError("boom", 500, {"error": "boom", "status": 500})
BAD_REPLY = QueryFailedError("bad reply", 502)


Case = tuple[int, str, Callable[[Harness], httpx.Response]]  # expected code, what, the request


def upstream_cases(method: str, path: str, process: str, **kwargs: Any) -> list[Case]:
    def with_state(**state: Any) -> Callable[[Harness], httpx.Response]:
        def run(h: Harness) -> httpx.Response:
            fail(h, **state)
            return h.send(method, path, **kwargs)

        return run

    return [
        (502, "an error reply", with_state(failure=ERROR_REPLY)),
        (502, "a reply the transport cannot decode", with_state(failure=BAD_REPLY)),
        (502, "a reply without the expected fields", with_state(unusable=True)),
        (503, f"no {process}", with_state(**{process: False})),
        (504, "no answer in time", with_state(failure=NO_ANSWER)),
    ]


def slow(method: str, path: str) -> Case:
    return 408, "a body that stops coming", lambda h: h.slow_body(method, path)


def big(method: str, path: str) -> Case:
    return 413, "a body over the cap", lambda h: h.send(method, path, content=b"{" + b" " * 20_000 + b"}", headers=AUTH)


def rate_limited(method: str, path: str, **kwargs: Any) -> Case:
    def run(h: Harness) -> httpx.Response:
        with h.client() as c:
            responses = [c.request(method, path, headers=AUTH, **kwargs) for _ in range(4)]
        assert 429 not in [r.status_code for r in responses[:3]]
        return responses[-1]

    return 429, "a fourth request at once (burst 3)", run


def at_cap(h: Harness) -> httpx.Response:
    fail(h, listing=[listed("a", "active"), listed("b", "pending")])
    return h.send("POST", "/faults", json=GOOD, headers=AUTH)


def get(path: str, **kwargs: Any) -> Callable[[Harness], httpx.Response]:
    return lambda h: h.send("GET", path, **kwargs)


def with_token(method: str, path: str, **kwargs: Any) -> Callable[[Harness], httpx.Response]:
    return lambda h: h.send(method, path, headers=AUTH, **kwargs)


CASES: dict[tuple[str, str], list[Case]] = {
    ("GET", "/health"): [(200, "ok", get("/health")), big("GET", "/health"), slow("GET", "/health")],
    ("GET", "/run"): [
        (200, "ok", get("/run")),
        big("GET", "/run"),
        slow("GET", "/run"),
        *upstream_cases("GET", "/run", "plant"),
    ],
    ("GET", "/faults"): [
        (200, "ok", get("/faults")),
        big("GET", "/faults"),
        slow("GET", "/faults"),
        *upstream_cases("GET", "/faults", "plant"),
    ],
    ("POST", "/faults"): [
        (201, "ok", with_token("POST", "/faults", json=GOOD)),
        (401, "no token", lambda h: h.send("POST", "/faults", json=GOOD)),
        (409, "a label that exists", with_token("POST", "/faults", json=GOOD | {"name": "known"})),
        (409, "the per-turbine cap (2)", at_cap),
        big("POST", "/faults"),
        slow("POST", "/faults"),
        (422, "a boolean value", with_token("POST", "/faults", json=GOOD | {"value": True})),
        rate_limited("POST", "/faults", json=GOOD | {"value": "x"}),
        *upstream_cases("POST", "/faults", "plant", json=GOOD, headers=AUTH),
    ],
    ("DELETE", "/faults/{label}"): [
        (200, "ok", with_token("DELETE", "/faults/known")),
        (401, "no token", lambda h: h.send("DELETE", "/faults/known")),
        (404, "no such label", with_token("DELETE", "/faults/nothing")),
        (409, "ended already", with_token("DELETE", "/faults/over")),
        big("DELETE", "/faults/known"),
        slow("DELETE", "/faults/known"),
        (422, "a control character", with_token("DELETE", "/faults/bad%01label")),
        rate_limited("DELETE", "/faults/nothing"),
        *upstream_cases("DELETE", "/faults/known", "plant", headers=AUTH),
    ],
    ("GET", "/supervisor/status"): [
        (200, "ok", get("/supervisor/status")),
        big("GET", "/supervisor/status"),
        slow("GET", "/supervisor/status"),
        *upstream_cases("GET", "/supervisor/status", "supervisor"),
    ],
    ("GET", "/supervisor/status/{turbine}"): [
        (200, "ok", get("/supervisor/status/1")),
        (404, "no such turbine", get("/supervisor/status/7")),
        big("GET", "/supervisor/status/1"),
        slow("GET", "/supervisor/status/1"),
        (422, "turbine 0", get("/supervisor/status/0")),
        *upstream_cases("GET", "/supervisor/status/1", "supervisor"),
    ],
    ("GET", "/events"): [
        (200, "ok", get("/events")),
        big("GET", "/events"),
        slow("GET", "/events"),
        (422, "since < 0", get("/events", params={"since": -1})),
    ],
    ("GET", "/metrics"): [(200, "ok", get("/metrics")), big("GET", "/metrics"), slow("GET", "/metrics")],
}
EXAMPLE_PATH = {template: template.replace("{label}", "known").replace("{turbine}", "1") for _, template in CASES}


def documented(harness: Harness) -> dict[tuple[str, str], set[int]]:
    schema = httpx.get(f"{harness.base}/openapi.json").json()
    return {
        (method.upper(), path): {int(code) for code in op["responses"]}
        for path, ops in schema["paths"].items()
        for method, op in ops.items()
    }


@pytest.mark.parametrize(
    "route, case",
    [(route, case) for route, cases in CASES.items() for case in cases],
    ids=[f"{m} {p} {c} {what}" for (m, p), cases in CASES.items() for c, what, _ in cases],
)
def test_each_case_gets_its_code(h, route, case):
    code, _, request = case
    response = request(h)
    assert response.status_code == code, response.text
    if code >= 400:
        assert response.headers["content-type"].startswith("application/json") and response.json()["detail"]
    if code in (429, 503) and response.json()["detail"].find("WINDWARDEN_API") >= 0:
        assert int(response.headers["retry-after"]) >= 1


def test_every_documented_code_has_a_case_and_every_case_is_documented(harness):
    schema = documented(harness)
    assert set(schema) == set(CASES), "routes without cases, or cases of no route"
    for route, cases in CASES.items():
        produced = {code for code, _, _ in cases} | {503}  # every route: the concurrency limit, tested below
        assert produced == schema[route], f"{route}: documented {sorted(schema[route])}, produced {sorted(produced)}"


def test_every_route_is_refused_with_503_while_the_api_is_at_its_concurrency_limit(h):
    """``api_max_concurrent=1``: one request held inside the bridge, every other one gets 503 and Retry-After."""
    h.bridge.gate = threading.Event()
    held: list[httpx.Response] = []
    holder = threading.Thread(target=lambda: held.append(h.send("GET", "/run")))
    holder.start()
    try:
        assert h.bridge.entered.wait(30)
        for method, template in CASES:
            kwargs = {"json": GOOD} if method == "POST" else {}
            response = h.send(method, EXAMPLE_PATH[template], headers=AUTH, **kwargs)
            assert response.status_code == 503 and response.headers["retry-after"] == "1", (template, response.text)
            assert "WINDWARDEN_API_MAX_CONCURRENT" in response.json()["detail"]
    finally:
        h.bridge.gate.set()
        holder.join(30)
    assert held[0].status_code == 200


@pytest.mark.parametrize(
    "state",
    [{}, {"plant": False}, {"supervisor": False}, {"failure": NO_ANSWER}, {"failure": ERROR_REPLY},
     {"failure": BAD_REPLY}, {"unusable": True}],
    ids=["healthy", "no-plant", "no-supervisor", "no-answer", "error-reply", "bad-reply", "unusable-reply"],
)  # fmt: skip
def test_no_route_returns_an_undocumented_code_whatever_the_plant_does(h, state):
    schema = documented(h)
    fail(h, **state)
    bodies: list[Any] = [GOOD, GOOD | {"turbine": "1"}, {}, [1], "x" * 100]
    for (method, template), codes in schema.items():
        path = EXAMPLE_PATH[template]
        for body, headers in itertools.product(bodies, (AUTH, {})):
            response = h.send(method, path, json=body, headers=headers)
            assert response.status_code in codes, (method, template, body, response.status_code, response.text)


def test_metric_labels_stay_bounded_whatever_the_method_or_path(h):
    for i in range(5):
        assert h.send(f"BREW{i}", "/faults").status_code == 405
        assert h.send("GET", f"/nothing/{i}").status_code == 404
    text = h.send("GET", "/metrics").text
    assert "BREW" not in text and "/nothing" not in text
    assert 'method="other",route="/faults",status="405"}' in text
    assert 'method="GET",route="unmatched",status="404"}' in text
