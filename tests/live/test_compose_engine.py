"""docker compose for real: build the image, ``up --wait``, read /health, inject a fault over REST, see it detected,
check that foreign Zenoh clients cannot publish references, ``down``. Needs a Docker engine with ``docker compose``
(``.ci/run`` starts one with ``../shared/tools/container-engine.sh``); skipped, with the reason, when there is none.

No container registry is reachable in CI, so the router runs from the project's image with the same zenohd
configuration file (docker/compose.ci.yaml); set ``WINDWARDEN_COMPOSE_ZENOHD=1`` to run the eclipse/zenoh image of
compose.yaml itself where it can be pulled. The timings (image build, up to healthy, fault detected, down) are
printed and written to ``compose-timings.json`` in the test's folder.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import threading
import time
from pathlib import Path

import httpx
import pytest
import zenoh

from tests.live.helpers import wait_for
from windwarden.live.access import new_passwords, password_file, write_credentials
from windwarden.live.config import ZenohSettings
from windwarden.live.router import free_port
from windwarden.live.transport import open_session
from wwcore.keys import KeyTree
from wwcore.wire import TURBINE_REFS

ROOT = Path(__file__).resolve().parents[2]
TOKEN = "compose-engine-token"
K = KeyTree("default")
BUILD_TIMEOUT_S = 480.0  # a cold build downloads the dependencies (~3 min on the 2-core machine)


def _engine() -> str | None:
    """Why there is no usable engine, or None."""
    if shutil.which("docker") is None:
        return "no docker CLI"
    for check in (["docker", "info"], ["docker", "compose", "version"]):
        try:
            done = subprocess.run(check, capture_output=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired) as error:
            return f"`{' '.join(check)}` failed: {error}"
        if done.returncode != 0:
            return f"`{' '.join(check)}` failed: {done.stderr.decode(errors='replace').strip()[:200]}"
    return None


REASON = _engine()
pytestmark = pytest.mark.skipif(REASON is not None, reason=f"no Docker engine ({REASON}); .ci/run starts one")


def test_compose_up_inject_detect_refuse_down(tmp_path):
    secrets = tmp_path / "secrets"
    write_credentials(secrets, new_passwords(), 0o644)  # the containers' user reads the mounted files
    ports = {name: free_port() for name in ("ZENOH_PORT", "WINDWARDEN_API_PORT", "RERUN_GRPC_PORT", "RERUN_WEB_PORT")}
    env = {k: v for k, v in os.environ.items() if not k.startswith(("WINDWARDEN_", "RUST_LOG"))}
    env |= {name: str(port) for name, port in ports.items()}
    env |= {
        "WINDWARDEN_API_TOKEN": TOKEN,
        "WINDWARDEN_SECRETS": str(secrets),
        "WINDWARDEN_SPEED": "2",
        "WINDWARDEN_RUN_ID": "compose-engine",
        "WINDWARDEN_IMAGE": "windwarden:compose-test",
    }
    files = ["-f", str(ROOT / "docker" / "compose.yaml")]
    if not os.environ.get("WINDWARDEN_COMPOSE_ZENOHD"):
        files += ["-f", str(ROOT / "docker" / "compose.ci.yaml")]
    compose = ["docker", "compose", "-p", f"wwtest{os.getpid()}", *files]

    def run(*args: str, timeout: float) -> float:
        start = time.monotonic()
        done = subprocess.run([*compose, *args], env=env, capture_output=True, text=True, timeout=timeout)
        if done.returncode != 0:
            ps = subprocess.run([*compose, "ps", "-a"], env=env, capture_output=True, text=True, timeout=60)
            logs = subprocess.run([*compose, "logs", "--tail", "15"], env=env, capture_output=True, text=True)
            pytest.fail(f"docker compose {' '.join(args)}:\n{done.stderr[-2000:]}\n{ps.stdout}\n{logs.stdout[-6000:]}")
        return time.monotonic() - start

    timings: dict[str, float] = {}
    try:
        timings["image build, s"] = run("build", timeout=BUILD_TIMEOUT_S)
        timings["up --wait to healthy, s"] = run("up", "-d", "--wait", "--wait-timeout", "180", timeout=240)
        api = httpx.Client(base_url=f"http://127.0.0.1:{ports['WINDWARDEN_API_PORT']}", timeout=5.0)
        health = api.get("/health").json()
        assert health["status"] == "ok" and health["plant"] and health["supervisor"], health
        assert wait_for(lambda: api.get("/run").json()["t"] > 11.0, 60), "the plant does not advance"
        now = api.get("/run").json()["t"]
        fault = {"target": "omega_r_m2", "kind": "fixed", "value": 0.5, "start_s": 0.0, "end_s": now + 8.0}
        sent = time.monotonic()
        response = api.post("/faults", json=fault, headers={"Authorization": f"Bearer {TOKEN}"})
        assert response.status_code == 201, response.text
        assert wait_for(lambda: "omega_r_m2" in api.get("/supervisor/status/1").json()["flagged"], 5.0, 0.005)
        timings["REST injection to detection in /supervisor/status/1, s"] = time.monotonic() - sent

        # foreign Zenoh clients on the published router port
        endpoint = f"tcp/127.0.0.1:{ports['ZENOH_PORT']}"
        with pytest.raises(zenoh.ZError):
            open_session(ZenohSettings(connect=endpoint, connect_timeout_s=2.0))
        viewer = {"zenoh_user": "viewer", "zenoh_password_file": password_file(secrets, "viewer")}
        with (
            open_session(ZenohSettings(connect=endpoint, **viewer)) as witness,
            open_session(ZenohSettings(connect=endpoint, **viewer)) as intruder,
        ):
            seen: list[bytes] = []
            lock = threading.Lock()

            def record(sample):
                with lock:
                    seen.append(sample.payload.to_bytes())

            received = api.get("/run").json()["refs_received"]
            witness.declare_subscriber(K.refs("*"), record)
            assert wait_for(lambda: len(seen) > 10, 10.0), "the witness sees no refs"
            rec = TURBINE_REFS.empty()[0]
            rec["tick"], rec["turbine"], rec["valid"], rec["omega_g"] = 10**15, 1, True, 200.0
            forged = TURBINE_REFS.encode(rec)
            for _ in range(50):
                intruder.put(K.refs("supervisor"), forged)
                time.sleep(0.01)
            time.sleep(1.0)
            with lock:
                assert forged not in seen, "a viewer's refs reached the plant's subscribers"
        # the plant still runs on the supervisor's references (fresh again within a second on a loaded machine)
        assert api.get("/run").json()["refs_received"] > received + 100
        assert wait_for(lambda: api.get("/run").json()["refs_fresh"], 5.0, 0.05)
        audit = subprocess.run(
            [*compose, "exec", "-T", "zenoh", "cat", "/runs/router.json"], env=env, capture_output=True, text=True
        )
        if audit.returncode == 0:  # the override's router counts; zenohd does not
            counts = json.loads(audit.stdout)
            assert any(d["role"] == "viewer" and d["key"] == K.refs("supervisor") for d in counts["denied"]), counts
            assert counts["logins_refused"].get("no credentials", 0) >= 1, counts
    finally:
        logs = subprocess.run([*compose, "logs", "--no-color"], env=env, capture_output=True, text=True, timeout=60)
        (tmp_path / "compose.log").write_text(logs.stdout + logs.stderr)
        timings["down, s"] = run("down", "-v", "--remove-orphans", timeout=120)
        (tmp_path / "compose-timings.json").write_text(json.dumps(timings, indent=2) + "\n")
        print(json.dumps(timings, indent=2))
    assert timings["down, s"] < 30.0, "a service ignores its stop signal"
