"""Real-time benchmark of the live system: ``windwarden up`` at ×1 for N seconds, then its figures.

Reports, from the run's scorecard (``live`` section, measured by the plant): ticks, overruns (ticks whose work ended
after their deadline) in %, the sensor→refs loop latency p50/p99/max, the real-time factor; the size of the
recording and its one-hour equivalent; for the turbine kind, the time from a REST injection of a speed-sensor fault
to its detection in the status route (measured from outside, over HTTP).

    .venv/bin/python tools/bench_live.py --kind turbine --seconds 300
    .venv/bin/python tools/bench_live.py --kind hydro --seconds 300
    .venv/bin/python tools/bench_live.py --kind farm --seconds 300 --offset 1450   # a drive-train hold in it
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from pathlib import Path

import httpx
import numpy as np

from windwarden.live.router import free_port
from wwcore.scenario import dump_scenario, load_scenario, parse_scenario

SCENARIOS = {"turbine": "ftwse-2012", "hydro": "hydro-fig9", "farm": "farm-case1"}


def bench_scenario(kind: str, seconds: float, folder: Path, offset: float = 0.0) -> Path:
    """The kind's shipped scenario from ``offset`` s on, cut to ``seconds`` (the mean wind and the faults moved
    back by ``offset``; faults outside the span left out or cut)."""
    base = load_scenario(SCENARIOS[kind])
    data = tomllib.loads(dump_scenario(base))
    data["name"] = f"bench-{kind}"
    data["duration_s"] = seconds
    if offset > 0.0:
        times, speeds = zip(*data["wind"]["mean"], strict=True)
        kept = [(t - offset, v) for t, v in zip(times, speeds, strict=True) if t > offset]
        data["wind"]["mean"] = [(0.0, float(np.interp(offset, times, speeds))), *kept]
    data["faults"] = [f for f in data.get("faults", []) if offset <= f["start_s"] < offset + seconds]
    for f in data["faults"]:
        f["start_s"] -= offset
        if f.get("end_s") is not None:
            f["end_s"] = min(f["end_s"] - offset, seconds)
    scenario = parse_scenario(data)
    path = folder / f"bench-{kind}.toml"
    path.write_text(dump_scenario(scenario))
    return path


def wait(predicate, timeout: float, interval: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if predicate():
                return True
        except (httpx.HTTPError, KeyError, ValueError):
            pass
        time.sleep(interval)
    return False


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", choices=sorted(SCENARIOS), default="turbine")
    parser.add_argument("--seconds", type=float, default=300.0, help="simulated = wall seconds at ×1")
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument("--runs-root", type=Path, default=Path("runs"))
    parser.add_argument("--nice", type=int, default=None, help="niceness of plant and supervisor (busy machines)")
    parser.add_argument("--inject-at", type=float, default=None, help="turbine: s of simulation time (default: half)")
    parser.add_argument("--offset", type=float, default=0.0, help="start this far into the shipped scenario (s)")
    args = parser.parse_args()

    folder = Path(tempfile.mkdtemp(prefix="bench-live-"))
    scenario = bench_scenario(args.kind, args.seconds, folder, args.offset)
    token = secrets.token_urlsafe(16)
    port = free_port()
    run_id = f"bench-{args.kind}-{time.strftime('%Y%m%d-%H%M%S')}"
    argv = [
        sys.executable,
        "-m",
        "windwarden.cli",
        "up",
        str(scenario),
        "--speed",
        str(args.speed),
        "--api-port",
        str(port),
        "--runs-root",
        str(args.runs_root),
        "--run-id",
        run_id,
        "--listen",
        f"tcp/127.0.0.1:{free_port()}",
        "--quiet",
        "--no-restart",
        *(["--nice", str(args.nice)] if args.nice is not None else []),
    ]
    env = os.environ | {"WINDWARDEN_API_TOKEN": token}
    print(f"running {' '.join(argv[3:])}", flush=True)
    up = subprocess.Popen(argv, env=env)
    try:
        return report(args, up, port, token, run_id)
    finally:
        if up.poll() is None:
            up.terminate()
            up.wait(60)


def sample_load(up: subprocess.Popen, into: list[float]) -> None:
    """The 1-minute load average every 5 s while the run lasts: the machine's other work, for the record."""
    while up.poll() is None:
        into.append(os.getloadavg()[0])
        time.sleep(5.0)


def report(args: argparse.Namespace, up: subprocess.Popen, port: int, token: str, run_id: str) -> int:
    figures: dict[str, object] = {}
    load: list[float] = []
    threading.Thread(target=sample_load, args=(up, load), daemon=True).start()
    api = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=5.0)
    if args.kind == "turbine":
        at = args.inject_at if args.inject_at is not None else args.seconds / 2
        if wait(lambda: api.get("/run").json()["t"] > at, args.seconds / args.speed + 120):
            fault = {
                "target": "omega_g_m2",
                "kind": "fixed",
                "value": 100.0,
                "start_s": 0.0,
                "end_s": min(at + 20.0, args.seconds - 1.0),
                "name": "bench injection",
            }
            sent = time.monotonic()
            response = api.post("/faults", json=fault, headers={"Authorization": f"Bearer {token}"})
            if response.status_code == 201 and wait(
                lambda: "omega_g_m2" in api.get("/supervisor/status/1").json()["flagged"], 5.0, 0.002
            ):
                figures["injection_to_status_detection_ms"] = 1e3 * (time.monotonic() - sent)
            else:
                figures["injection_to_status_detection_ms"] = f"not seen ({response.status_code}: {response.text})"
    code = up.wait()
    api.close()
    run_dir = args.runs_root / run_id
    card = json.loads((run_dir / "scorecard.json").read_text())
    live = card["live"]
    size = (run_dir / "recording.rrd").stat().st_size
    figures |= {
        "exit_code": code,
        "ticks": live["ticks"],
        "overruns": live["overruns"],
        "overrun_pct": round(live["overrun_pct"], 3),
        "resyncs": live["resyncs"],
        "latency_ms": {k: (round(v, 3) if isinstance(v, float) else v) for k, v in live["latency"].items()},
        "real_time_factor": live["real_time_factor"],
        "ticks_without_refs": live["ticks_without_refs"],
        "recording_bytes": size,
        "recording_1h_estimate_mb": round(size * 3600.0 / args.seconds / 1e6, 1),
        "run_dir": str(run_dir),
        "nice": args.nice,
        "load_average_1min": {
            "min": min(load, default=None),
            "mean": sum(load) / max(len(load), 1),
            "max": max(load, default=None),
            "cpus": os.cpu_count(),
        },
    }
    print(json.dumps(figures, indent=2))
    (run_dir / "bench.json").write_text(json.dumps(figures, indent=2) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main())
