"""docker/compose.yaml is real: each service's command, environment and health check, run as a local process.

There is no Docker engine here, so the test reads compose.yaml (and the Dockerfile's ENTRYPOINT), interpolates its
variables, maps each container's host name and ports to 127.0.0.1 and free local ports (what the compose network
does), replaces the ``zenoh`` image by the embedded router, starts every other service's command, waits until
each health check passes, then injects a fault over REST and sees it detected.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import httpx
import yaml

from tests.live.helpers import wait_for
from windwarden.live.recorder import stop
from windwarden.live.router import free_port, open_router

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "docker" / "compose.yaml"
DOCKERFILE = ROOT / "docker" / "Dockerfile"
ORDER = ["rerun", "viewer", "supervisor", "plant", "api"]  # depends_on order
TOKEN = "compose-token"


def interpolate(text: str, env: dict[str, str]) -> str:
    """Compose's ${VAR}, ${VAR:-default} and ${VAR:?error}."""

    def one(match: re.Match) -> str:
        name, op, arg = match.group(1), match.group(2), match.group(3)
        value = env.get(name)
        if op == ":?" and not value:
            raise AssertionError(f"compose needs {name}: {arg}")
        return value if value else (arg or "" if op == ":-" else "")

    return re.sub(r"\$\{(\w+)(?:(:-|:\?)([^}]*))?\}", one, text)


def entrypoint() -> list[str]:
    line = next(x for x in DOCKERFILE.read_text().splitlines() if x.startswith("ENTRYPOINT"))
    return json.loads(line.split(None, 1)[1])


def test_compose_services_run_locally_and_work(tmp_path):
    ports = {
        ("zenoh", 7447): free_port(),
        ("rerun", 9876): free_port(),
        ("api", 8000): free_port(),
        ("viewer", 9090): free_port(),
    }
    env_host = {
        "WINDWARDEN_API_TOKEN": TOKEN,
        "WINDWARDEN_SPEED": "2",
        "WINDWARDEN_RUN_ID": "compose-test",
        "RERUN_GRPC_PORT": str(ports[("rerun", 9876)]),
    }
    compose = yaml.safe_load(interpolate(COMPOSE.read_text(), env_host))
    services = compose["services"]
    assert set(services) == {"zenoh", *ORDER}
    assert services["zenoh"]["image"].startswith("eclipse/zenoh:1.10")
    runs = tmp_path / "runs"

    def localise(text: str, service: str) -> str:
        for (host, port), local in ports.items():
            text = text.replace(f"{host}:{port}", f"127.0.0.1:{local}")
            if host == service:  # the container's own ports, as an argument or in its own URLs
                for me in ("127.0.0.1", "0.0.0.0", "localhost"):
                    text = text.replace(f"{me}:{port}", f"{me}:{local}")
                text = re.sub(rf"(?<![\d.:]){port}(?!\d)", str(local), text)
        return text.replace("/runs", str(runs))

    def argv(spec: dict, service: str) -> list[str]:
        entry = spec.get("entrypoint", entrypoint())
        return [localise(str(a), service) for a in [*entry, *spec["command"]]]

    base_env = {k: v for k, v in os.environ.items() if not k.startswith("WINDWARDEN_")}
    base_env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{base_env.get('PATH', '')}"
    procs: dict[str, subprocess.Popen] = {}
    log = (tmp_path / "services.log").open("ab")
    with open_router([f"tcp/127.0.0.1:{ports[('zenoh', 7447)]}"]):
        try:
            for name in ORDER:
                spec = services[name]
                env = base_env | {k: localise(str(v), name) for k, v in spec.get("environment", {}).items()}
                procs[name] = subprocess.Popen(
                    argv(spec, name), env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
                )
                check = spec.get("healthcheck", {}).get("test")
                if check:
                    assert check[0] == "CMD", f"{name}: health checks are exec form"
                    probe = [localise(str(a), name) for a in check[1:]]

                    def healthy(probe=probe, env=env) -> bool:
                        return subprocess.run(probe, env=env, capture_output=True, timeout=30).returncode == 0

                    assert wait_for(healthy, 60, 0.5), f"{name} never became healthy: {probe}"
                assert procs[name].poll() is None, f"{name} exited"
            viewer = f"http://127.0.0.1:{ports[('viewer', 9090)]}/"
            assert wait_for(lambda: _ok(viewer), 30), "the web viewer does not serve"
            api = httpx.Client(base_url=f"http://127.0.0.1:{ports[('api', 8000)]}", timeout=5.0)
            assert api.get("/health").json() | {"uptime_s": 0} == {
                "status": "ok",
                "zenoh": "open",
                "plant": True,
                "supervisor": True,
                "uptime_s": 0,
            }
            assert wait_for(lambda: api.get("/run").json()["t"] > 11.0, 60)
            now = api.get("/run").json()["t"]
            fault = {"target": "omega_r_m2", "kind": "fixed", "value": 0.5, "start_s": 0.0, "end_s": now + 6.0}
            response = api.post("/faults", json=fault, headers={"Authorization": f"Bearer {TOKEN}"})
            assert response.status_code == 201, response.text
            assert wait_for(lambda: "omega_r_m2" in api.get("/supervisor/status/1").json()["flagged"], 2.0, 0.01)
            assert (runs / "compose-test" / "recording.rrd").exists()
            assert (runs / "compose-test" / "events.jsonl").exists()
        finally:
            for proc in reversed(procs.values()):
                stop(proc)  # the whole process group: `sh -c "exec rerun …"` has children of its own
            log.close()


def _ok(url: str) -> bool:
    try:
        return httpx.get(url, timeout=2.0).status_code == 200
    except httpx.HTTPError:
        return False
