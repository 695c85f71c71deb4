"""End to end: ``windwarden up`` in the background, a fault injected over REST, its detection seen in the status
route and in events.jsonl, a clean shutdown at the scenario's end, and a recording that verifies and holds the
dashboard's entities (plant and supervisor in one recording)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import httpx
import pytest

from tests.live.helpers import wait_for
from windwarden.live.finalize import recording_entities, verify_recording
from windwarden.live.router import EPHEMERAL_RANGE, LOWEST_LISTEN_PORT, free_port
from windwarden.live.runfolder import EVENTS, RECORDING, read_events

SCENARIO = """
name = "up-e2e"
duration_s = 30.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0]]
"""
TOKEN = "e2e-token"


def test_up_inject_detect_shutdown_recording(tmp_path):
    (tmp_path / "s.toml").write_text(SCENARIO)
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("WINDWARDEN_")} | {"WINDWARDEN_API_TOKEN": TOKEN}
    argv = [
        sys.executable,
        "-m",
        "windwarden.cli",
        "up",
        str(tmp_path / "s.toml"),
        "--speed",
        "2",
        "--api-port",
        str(port),
        "--runs-root",
        str(tmp_path / "runs"),
        "--run-id",
        "e2e",
        "--listen",
        f"tcp/127.0.0.1:{free_port()}",
        "--quiet",
    ]
    up = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    run_dir = tmp_path / "runs" / "e2e"
    api = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=5.0)
    try:

        def healthy():
            try:
                h = api.get("/health").json()
            except httpx.HTTPError:
                return False
            return h["plant"] and h["supervisor"]

        assert wait_for(healthy, 60), "the system did not come up"
        assert wait_for(lambda: api.get("/run").json().get("t", 0.0) > 12.0, 60), "no progress (warm-up)"
        now = api.get("/run").json()["t"]
        fault = {
            "target": "omega_r_m1",
            "kind": "fixed",
            "value": 1.4,
            "start_s": 0.0,
            "end_s": min(now + 8.0, 29.0),
            "name": "rest fault",
        }
        response = api.post("/faults", json=fault, headers={"Authorization": f"Bearer {TOKEN}"})
        assert response.status_code == 201, response.text
        assert wait_for(lambda: "omega_r_m1" in api.get("/supervisor/status/1").json()["flagged"], 2.0, 0.01)
        assert wait_for(
            lambda: any(
                e.type.value == "detection" and e.target == "omega_r_m1" for e in read_events(run_dir / EVENTS)
            ),
            2.0,
        )
        output, _ = up.communicate(timeout=120)
    finally:
        if up.poll() is None:
            up.terminate()
            up.wait(30)
        api.close()
    assert up.returncode == 0, output
    events = read_events(run_dir / EVENTS)
    injected = [e for e in events if e.type.value == "fault_injected"]
    assert [e.detail["label"] for e in injected] == ["rest fault"]
    first_detection = min(e.t for e in events if e.type.value == "detection" and e.target == "omega_r_m1")
    assert 0.0 <= first_detection - injected[0].t < 1.0
    card = json.loads((run_dir / "scorecard.json").read_text())
    assert card["live"]["completed"] and [f["name"] for f in card["faults"]] == ["rest fault"]
    assert card["faults"][0]["detected_pct"] == 100.0 and card["faults"][0]["isolated_pct"] == 100.0
    summary = json.loads((run_dir / "up.json").read_text())
    assert summary["completed"] and summary["failed"] == [] and summary["recording_verified"]
    recording = run_dir / RECORDING
    assert verify_recording(recording)
    entities = recording_entities(recording)
    expected = {
        "/turbine/1/speed/omega_r/plant",  # sensors and truth, from the plant
        "/turbine/1/speed/omega_r/supervisor",  # the fault-tolerant estimate, from the supervisor
        "/turbine/1/speed/omega_g/plant",
        "/turbine/1/speed/omega_g/supervisor",
        "/turbine/1/wind/plant",  # anemometer and true rotor-effective wind
        "/turbine/1/wind/supervisor",  # FTE and NFTE
        "/turbine/1/residuals/supervisor",  # residual / threshold per observer, and the threshold
        "/turbine/1/faults/injected/omega_r_m1",
        "/turbine/1/faults/detected/omega_r_m1",
        "/turbine/1/observer",
        "/events",
        "/run/timing",
    }
    assert expected <= entities, expected - entities
    for child in ("plant", "supervisor", "api"):
        assert (run_dir / "logs" / f"{child}.log").exists()


@pytest.mark.in_process
def test_free_ports_are_drawn_below_the_ephemeral_range():
    """``free_port`` leaves the kernel's ephemeral range to outgoing connections where it knows it (Linux), so no
    connection of another process can take the port before the caller listens on it; each port is bindable."""
    if not EPHEMERAL_RANGE.exists():
        pytest.skip("no ephemeral port range to read on this system")
    low = int(EPHEMERAL_RANGE.read_text().split()[0])
    ports = [free_port() for _ in range(20)]
    assert all(LOWEST_LISTEN_PORT <= p < low for p in ports), ports
    for port in ports[:3]:
        with socket.socket() as s:
            s.bind(("127.0.0.1", port))
