"""docker/compose.yaml, without a container engine: each service's command, environment, secrets and health check,
run as a local process.

The test reads compose.yaml with the CI override (docker/compose.ci.yaml: the router is ``windwarden router`` with
the zenohd configuration file, instead of the eclipse/zenoh image) and the Dockerfile's ENTRYPOINT, interpolates the
variables, maps each container's host name and ports to 127.0.0.1 and free local ports (what the compose network
does), the secrets and mounted files to local files, starts every service's command, waits until each health check
passes, injects a fault over REST and sees it detected, and checks that a client without credentials cannot join.
``tests/live/test_compose_engine.py`` runs the same files with a real Docker engine.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
import yaml
import zenoh

from tests.live.helpers import wait_for
from windwarden.live.access import new_passwords, write_credentials
from windwarden.live.config import ZenohSettings
from windwarden.live.recorder import stop
from windwarden.live.router import free_port
from windwarden.live.transport import open_session

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "docker" / "compose.yaml"
OVERRIDE = ROOT / "docker" / "compose.ci.yaml"
DOCKERFILE = ROOT / "docker" / "Dockerfile"
ORDER = ["zenoh", "rerun", "viewer", "supervisor", "plant", "api"]  # depends_on order
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


def load(env: dict[str, str]) -> dict:
    """compose.yaml with the override merged the way compose merges it (mappings deep, scalars and commands
    replaced, volumes appended)."""
    base = yaml.safe_load(interpolate(COMPOSE.read_text(), env))
    over = yaml.safe_load(interpolate(OVERRIDE.read_text(), env))
    for name, spec in over["services"].items():
        merged = base["services"][name]
        for key, value in spec.items():
            if key == "volumes":
                merged[key] = [*merged.get(key, []), *value]
            elif isinstance(value, dict) and isinstance(merged.get(key), dict):
                merged[key] = merged[key] | value
            else:
                merged[key] = value
    return base


@pytest.mark.in_process
def test_compose_files_pin_one_build_and_fast_stops():
    env = {"WINDWARDEN_API_TOKEN": TOKEN}
    base = yaml.safe_load(interpolate(COMPOSE.read_text(), env))
    services = base["services"]
    assert [name for name, s in services.items() if "build" in s] == ["supervisor"], "one image build"
    assert services["zenoh"]["image"].startswith("eclipse/zenoh:1.10")
    assert "--rest-http-port" in services["zenoh"]["command"]  # the health check needs the REST plugin loaded
    assert "127.0.0.1:" in services["zenoh"]["command"][services["zenoh"]["command"].index("--rest-http-port") + 1]
    for name, spec in services.items():
        assert spec.get("init") is True, f"{name}: a real PID 1 forwards stop signals"
        if name != "zenoh":
            assert spec["image"] == "windwarden:local" and spec["pull_policy"] == "never"
    for name in ("rerun", "viewer"):
        assert services[name]["stop_signal"] == "SIGINT"
    for name in ("plant", "supervisor", "api"):
        creds = services[name]["environment"]
        assert creds["WINDWARDEN_ZENOH_USER"] == name
        assert creds["WINDWARDEN_ZENOH_PASSWORD_FILE"] == f"/run/secrets/zenoh_{name}"
        assert f"zenoh_{name}" in services[name]["secrets"]
        assert not any("password" in str(a).lower() for a in services[name].get("command", []))


def test_compose_services_run_locally_and_work(tmp_path):
    ports = {
        ("zenoh", 7447): free_port(),
        ("rerun", 9876): free_port(),
        ("api", 8000): free_port(),
        ("viewer", 9090): free_port(),
    }
    secrets = tmp_path / "secrets"
    write_credentials(secrets, new_passwords(), 0o644)
    env_host = {
        "WINDWARDEN_API_TOKEN": TOKEN,
        "WINDWARDEN_SPEED": "2",
        "WINDWARDEN_RUN_ID": "compose-test",
        "RERUN_GRPC_PORT": str(ports[("rerun", 9876)]),
        "WINDWARDEN_SECRETS": str(secrets),
    }
    compose = load(env_host)
    services = compose["services"]
    assert set(services) == set(ORDER)
    runs = tmp_path / "runs"
    runs.mkdir()
    secret_files = {
        f"/run/secrets/{name}": str((COMPOSE.parent / s["file"]).resolve()) for name, s in compose["secrets"].items()
    }
    mounts: dict[str, str] = {}
    for spec in services.values():
        for volume in spec.get("volumes", []):
            source, _, target = volume.partition(":")
            if source.startswith("./"):
                mounts[target.split(":")[0]] = str(tmp_path / Path(source).name)
    router_file = (COMPOSE.parent / "zenoh" / "router.json5").read_text()
    for target, local in secret_files.items():
        router_file = router_file.replace(target, local)
    (tmp_path / "router.json5").write_text(router_file)

    def localise(text: str, service: str) -> str:
        for (host, port), local in ports.items():
            text = text.replace(f"{host}:{port}", f"127.0.0.1:{local}")
            if host == service:  # the container's own ports, as an argument or in its own URLs
                for me in ("127.0.0.1", "0.0.0.0", "localhost"):
                    text = text.replace(f"{me}:{port}", f"{me}:{local}")
                text = re.sub(rf"(?<![\d.:]){port}(?!\d)", str(local), text)
        for target, local in [*secret_files.items(), *mounts.items()]:
            text = text.replace(target, local)
        return text.replace("/runs", str(runs))

    def argv(spec: dict, service: str) -> list[str]:
        entry = spec.get("entrypoint", entrypoint())
        args = [localise(str(a), service) for a in [*entry, *spec["command"]]]
        if service == "zenoh":  # the container's 0.0.0.0:7447 comes from the configuration file
            args += ["--listen", f"tcp/127.0.0.1:{ports[('zenoh', 7447)]}"]
        return args

    base_env = {k: v for k, v in os.environ.items() if not k.startswith(("WINDWARDEN_", "RUST_LOG"))}
    base_env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{base_env.get('PATH', '')}"
    procs: dict[str, subprocess.Popen] = {}
    log = (tmp_path / "services.log").open("ab")
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

                if not wait_for(healthy, 60, 0.5):
                    log.flush()
                    tail = (tmp_path / "services.log").read_text(errors="replace")[-4000:]
                    pytest.fail(f"{name} never became healthy: {probe}\nthe services' log ends:\n{tail}")
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
        endpoint = f"tcp/127.0.0.1:{ports[('zenoh', 7447)]}"
        with pytest.raises(zenoh.ZError):
            open_session(ZenohSettings(connect=endpoint, connect_timeout_s=1.0))
    finally:
        for proc in reversed(procs.values()):
            stop(proc)  # the whole process group: `sh -c "exec rerun …"` has children of its own
        log.close()
    counts = json.loads((runs / "router.json").read_text())
    assert counts["logins_refused"].get("no credentials", 0) >= 1 and counts["denied_total"] == 0, counts


def _ok(url: str) -> bool:
    try:
        return httpx.get(url, timeout=2.0).status_code == 200
    except httpx.HTTPError:
        return False
