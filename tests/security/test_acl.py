"""Hostile Zenoh clients against a live system on loopback (``windwarden up``: router with access control, plant,
supervisor, API), holding no credentials, a wrong password, or the credentials of another role (read from the run's
own secrets folder: the worst case of a leaked password).

Each probe must be refused and counted, the plant must keep running on the supervisor's references, and nothing
already in ``events.jsonl`` may be lost:

* no credentials, wrong password: the session cannot open (counted by the router as refused logins);
* forged refs (``valid``, ``omega_g = 200``, tick 10¹⁵: adopted, they would stop the rotor and hold the plant for the
  rest of the run) from the plant, API and viewer roles;
* stale sensor frames (tick 0: delivered, they would restart the observers) from the supervisor, API and viewer;
* forged detection events on the plant's and the supervisor's event keys from every other role;
* a fault injected by querying ``plant/faults`` directly (only the API may) from the supervisor and viewer roles.

How refusals are counted: the router drops them (access control) and its audit counts each dropped message by role,
message kind and key, and each refused login by reason (``runs/<id>/router.json``, from Zenoh's trace log; Zenoh
keeps no counter of its own). A refused query gets no reply at all: the asker sees an empty answer at once. At the
receiving side nothing arrives, which a viewer session subscribed to everything confirms.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time

import httpx
import pytest
import zenoh

from tests.live.helpers import wait_for
from windwarden.live.access import password_file
from windwarden.live.config import ZenohSettings
from windwarden.live.router import free_port
from windwarden.live.runfolder import EVENTS
from windwarden.live.transport import open_session, query_json
from wwcore.events import Event, EventType
from wwcore.keys import KeyTree
from wwcore.wire import TURBINE_REFS, TURBINE_SENSORS, encode_json

SCENARIO = """
name = "acl-probes"
duration_s = 18.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0]]
"""
TOKEN = "acl-probe-token"
K = KeyTree("default")
FORGED_TICK = 10**15


def forged_refs() -> bytes:
    rec = TURBINE_REFS.empty()[0]
    rec["tick"], rec["turbine"], rec["valid"] = FORGED_TICK, 1, True
    rec["omega_g"], rec["omega_r"], rec["wind"], rec["selected"] = 200.0, 200.0 / 97.0, 12.0, 0
    return TURBINE_REFS.encode(rec)


def stale_sensors() -> bytes:
    rec = TURBINE_SENSORS.empty()[0]
    rec["tick"], rec["t"], rec["turbine"] = 0, 0.0, 1
    return TURBINE_SENSORS.encode(rec)


def forged_event(role: str) -> bytes:
    event = Event(1.0, EventType.DETECTION, target=f"forged-by-{role}", detail={"noticed_by": role})
    return encode_json("events", event.to_json())


@pytest.fixture
def live_system(tmp_path):
    (tmp_path / "s.toml").write_text(SCENARIO)
    api_port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("WINDWARDEN_", "RUST_LOG"))}
    env["WINDWARDEN_API_TOKEN"] = TOKEN
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    argv = [sys.executable, "-m", "windwarden.cli", "up", str(tmp_path / "s.toml"), "--speed", "1"]
    argv += ["--api-port", str(api_port), "--runs-root", str(tmp_path / "runs"), "--run-id", "acl"]
    argv += ["--listen", endpoint, "--quiet"]
    up = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        yield up, endpoint, tmp_path / "runs" / "acl", httpx.Client(base_url=f"http://127.0.0.1:{api_port}", timeout=5)
    finally:
        if up.poll() is None:
            up.terminate()
            up.wait(60)


def test_hostile_clients_are_refused_and_counted(live_system):
    up, endpoint, run_dir, api = live_system
    secrets = run_dir / "secrets"

    def healthy() -> bool:
        try:
            h = api.get("/health").json()
        except httpx.HTTPError:
            return False
        return bool(h.get("plant") and h.get("supervisor"))

    assert wait_for(healthy, 90), "the system did not come up"

    def session(role: str | None, password: str | None = None, **extra) -> zenoh.Session:
        creds = {}
        if role is not None:
            creds = {"zenoh_user": role, "zenoh_password_file": password_file(secrets, role)}
            if password is not None:
                (run_dir.parent / "wrong.password").write_text(password + "\n")
                creds["zenoh_password_file"] = run_dir.parent / "wrong.password"
        return open_session(ZenohSettings(connect=endpoint, **creds, **extra))

    api_session = session("api")

    def plant_status() -> dict:
        return query_json(api_session, K.plant_status, "plant.status", timeout=2.0)

    def supervisor_status() -> dict:
        return query_json(api_session, K.supervisor_status, "supervisor.status", timeout=2.0)

    assert wait_for(lambda: plant_status()["refs_fresh"] and plant_status()["t"] > 5.0, 60), "refs never fresh"
    events_before = (run_dir / EVENTS).read_bytes()
    restarts_before = supervisor_status()["observer_restarts"]
    faults_before = {k: v for k, v in api.get("/faults").json().items() if k != "t"}

    # no credentials, a wrong password: no session
    with pytest.raises(zenoh.ZError):
        session(None, connect_timeout_s=1.0)
    with pytest.raises(zenoh.ZError):
        session("supervisor", password="guessed", connect_timeout_s=1.0)

    # a witness that sees everything the router lets through
    witness = session("viewer")
    seen: list[tuple[str, bytes]] = []
    lock = threading.Lock()

    def record(sample):
        with lock:
            seen.append((str(sample.key_expr), sample.payload.to_bytes()))

    witness.declare_subscriber(f"{K.base}/**", record)
    hostile = {role: session(role) for role in ("plant", "supervisor", "api", "viewer")}
    probes = {
        K.refs("supervisor"): (forged_refs(), ("plant", "api", "viewer")),
        K.sensors: (stale_sensors(), ("supervisor", "api", "viewer")),
        K.plant_events: (None, ("supervisor", "api", "viewer")),
        K.supervisor_events: (None, ("plant", "api", "viewer")),
    }
    received_before = plant_status()["refs_received"]
    for _ in range(50):  # 0.5 s of forged traffic at 100 Hz per probe
        for key, (payload, roles) in probes.items():
            for role in roles:
                hostile[role].put(key, payload if payload is not None else forged_event(role))
        time.sleep(0.01)
    injections = {}
    for role in ("supervisor", "viewer"):
        fault = {"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 0.0, "end_s": 30.0}
        command = encode_json("plant.faults", {"op": "inject", "fault": fault})
        replies = list(hostile[role].get(K.faults, payload=command))
        injections[role] = [r.ok is not None for r in replies]
    time.sleep(1.0)

    # nothing got through ...
    with lock:
        forged = [(k, p) for k, p in seen if p == forged_refs() or p == stale_sensors() or b"forged-by-" in p]
    assert forged == [], forged[:3]
    assert injections == {"supervisor": [], "viewer": []}, "a fault command reached the plant"
    # ... the plant runs on the supervisor's references ...
    status = plant_status()
    assert status["refs_fresh"], status
    assert status["refs_received"] > received_before + 50, "the supervisor's refs stopped arriving"
    assert supervisor_status()["observer_restarts"] == restarts_before, "stale sensor frames restarted the observers"
    assert {k: v for k, v in api.get("/faults").json().items() if k != "t"} == faults_before
    # ... and nothing already in events.jsonl is lost, nothing forged is in it
    after = (run_dir / EVENTS).read_bytes()
    assert after.startswith(events_before)
    assert b"forged-by-" not in after
    assert not [e for e in api.get("/events").json()["events"] if str(e.get("target", "")).startswith("forged")]
    for s in [*hostile.values(), witness, api_session]:
        s.close()

    out, _ = up.communicate(timeout=120)
    assert up.returncode == 0, out[-3000:]
    counts = json.loads((run_dir / "router.json").read_text())
    denied = {(d["role"], d["key"]) for d in counts["denied"] if d["message"] == "put" and d["flow"] == "ingress"}
    for key, (_, roles) in probes.items():
        for role in roles:
            assert (role, key) in denied, f"{role}'s put on {key} was not counted"
    queries = {(d["role"], d["key"]) for d in counts["denied"] if d["message"] == "query"}
    assert {("supervisor", K.faults), ("viewer", K.faults)} <= queries
    assert counts["logins_refused"].get("no credentials", 0) >= 1
    assert counts["logins_refused"].get("wrong password", 0) >= 1
    legit = {d["role"] for d in counts["denied"]} - {"plant", "supervisor", "api", "viewer"}
    assert not legit, f"denials counted for unknown subjects: {legit}"
    up_json = json.loads((run_dir / "up.json").read_text())
    assert up_json["access_control"] and up_json["router_refused"]["denied_total"] == counts["denied_total"]
    # the credentials: private files, and no password in any log, in up's output or in the run's JSON files
    assert secrets.stat().st_mode & 0o777 == 0o700
    passwords = []
    for path in secrets.iterdir():
        assert path.stat().st_mode & 0o777 == 0o600, path
        if path.suffix == ".password":
            passwords.append(path.read_text().strip())
    written = [out, *(p.read_text(errors="replace") for p in [*run_dir.glob("*.json"), *(run_dir / "logs").glob("*")])]
    assert len(passwords) == 4 and not [pw for pw in passwords if any(pw in text for text in written)]
