"""Real-time benchmark of the live system: ``windwarden up`` at ×1 for N seconds, then its figures.

Reports, from the run's scorecard (``live`` section, measured by the plant): ticks, overruns (ticks whose work ended
after their deadline) in %, the sensor→refs loop latency p50/p99/max, the real-time factor; the size of the
recording and its one-hour equivalent; the CPU seconds per wall second of each of ``up``'s children (plant,
supervisor or shards and coordinator, router, API, Rerun), which unlike the latencies hardly depend on the
machine's other work; for the turbine kind, the time from a REST injection of a speed-sensor fault
to its detection in the status route (measured from outside, over HTTP).

    .venv/bin/python tools/bench_live.py --kind turbine --seconds 300
    .venv/bin/python tools/bench_live.py --kind hydro --seconds 300
    .venv/bin/python tools/bench_live.py --kind farm --seconds 300 --offset 1450   # a drive-train hold in it
    .venv/bin/python tools/bench_live.py --kind farm --scenario farm-hornsrev1 --seconds 300   # 80 turbines

A sharded supervisor (two shards and a coordinator, ``up --shards 2``) beside one supervisor, on Horns Rev 1's 80
turbines, interleaved:

    .venv/bin/python tools/bench_live.py --kind farm --scenario farm-hornsrev1 --seconds 120 --compare-shards

What access control costs: ``--compare-acl`` runs the same benchmark back to back with an open router
(``up --no-acl``) and with the router ``up`` runs by default (access control, user/password per role, and the audit
that counts refusals from Zenoh's trace log), and prints both with the ratios of their loop latencies; add
``--acl-modes open,acl,acl-noaudit`` to separate the audit's share:

    .venv/bin/python tools/bench_live.py --kind turbine --seconds 120 --compare-acl
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
import psutil

from windwarden.live.router import free_port
from wwcore.scenario import dump_scenario, load_scenario, parse_scenario

SCENARIOS = {"turbine": "ftwse-2012", "hydro": "hydro-fig9", "farm": "farm-case1"}
ACL_MODES = {  # name → flags of `windwarden up`
    "open": ["--no-acl"],
    "acl": [],
    "acl-noaudit": ["--no-router-audit"],
}


def bench_scenario(kind: str, seconds: float, folder: Path, offset: float = 0.0, name: str | None = None) -> Path:
    """The shipped scenario ``name`` (default: the kind's, ``SCENARIOS``) from ``offset`` s on, cut to ``seconds``
    (the mean wind and the faults moved back by ``offset``; faults outside the span left out or cut)."""
    base = load_scenario(name or SCENARIOS[kind])
    if base.plant.kind != kind:
        raise SystemExit(f"--scenario {name}: a {base.plant.kind} scenario, not {kind}")
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
    parser.add_argument("--scenario", default=None, help="a shipped scenario of --kind (default: the kind's own)")
    parser.add_argument(
        "--shards",
        type=int,
        default=0,
        help="farm: a sharded supervisor (up --shards N: N shards and a coordinator); 0: one supervisor",
    )
    parser.add_argument(
        "--compare-shards",
        action="store_true",
        help="farm: run with one supervisor, then with --shards N (default 2), and compare their loop latencies",
    )
    parser.add_argument("--compare-acl", action="store_true", help="run without and with access control, compare")
    parser.add_argument(
        "--acl-modes",
        default="open,acl",
        help=f"with --compare-acl: configurations to run in order, from {', '.join(ACL_MODES)} (default open,acl)",
    )
    parser.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="with --compare-acl or --compare-shards: run the configurations this many times, interleaved",
    )
    args = parser.parse_args()
    if args.compare_shards:
        return compare_shards(args)
    if not args.compare_acl:
        sharded = ["--shards", str(args.shards)] if args.shards else []
        return 0 if run_once(args, sharded, f"-shards{args.shards}" if args.shards else "")[0] == 0 else 1
    modes = [m.strip() for m in args.acl_modes.split(",") if m.strip()]
    unknown = [m for m in modes if m not in ACL_MODES]
    if unknown or not modes:
        parser.error(f"unknown --acl-modes {unknown}; choose from {', '.join(ACL_MODES)}")
    results: dict[str, list[dict]] = {mode: [] for mode in modes}
    for _ in range(max(args.repeat, 1)):
        for mode in modes:
            code, figures = run_once(args, ACL_MODES[mode], f"-{mode}")
            results[mode].append(figures)
            if code != 0:
                print(f"{mode}: up exited with {code}", flush=True)
    print(json.dumps(compare(results), indent=2))
    return 0


def compare_shards(args: argparse.Namespace) -> int:
    """One supervisor, then ``--shards`` N (default 2) and a coordinator, interleaved ``--repeat`` times; the
    medians of their loop latencies and the ratios to one supervisor's (``compare``)."""
    if args.kind != "farm":
        raise SystemExit("--compare-shards: a farm's supervisor is sharded; give --kind farm")
    shards = args.shards or 2
    configurations = {"one-supervisor": [], f"{shards}-shards": ["--shards", str(shards)]}
    results: dict[str, list[dict]] = {name: [] for name in configurations}
    for _ in range(max(args.repeat, 1)):
        for name, extra in configurations.items():
            code, figures = run_once(args, extra, f"-{name}")
            results[name].append(figures)
            if code != 0:
                print(f"{name}: up exited with {code}", flush=True)
    print(json.dumps(compare(results), indent=2))
    return 0


def compare(results: dict[str, list[dict]]) -> dict[str, object]:
    """Per configuration: each run's loop latency p50/p99/max and overruns, their medians over the runs, and the
    ratio of those medians to the first configuration's."""
    table: dict[str, dict] = {}
    for mode, runs in results.items():
        rows = [
            {
                "p50_ms": f.get("latency_ms", {}).get("p50_ms"),
                "p99_ms": f.get("latency_ms", {}).get("p99_ms"),
                "max_ms": f.get("latency_ms", {}).get("max_ms"),
                "overrun_pct": f.get("overrun_pct"),
                "load_average_1min_mean": round(f.get("load_average_1min", {}).get("mean") or 0.0, 2),
                "cpu_per_wall_s": f.get("cpu_per_wall_s"),
                "run_dir": f.get("run_dir"),
            }
            for f in runs
        ]
        table[mode] = {
            "p50_ms": _median([r["p50_ms"] for r in rows]),
            "p99_ms": _median([r["p99_ms"] for r in rows]),
            "runs": rows,
        }
    base_mode = next(iter(table))
    base = table[base_mode]
    for mode in list(table)[1:]:
        row = table[mode]
        for q in ("p50_ms", "p99_ms"):
            if row[q] and base[q]:
                row[f"{q.removesuffix('_ms')}_ratio_to_{base_mode}"] = round(row[q] / base[q], 3)
    return table


def _median(values: list) -> float | None:
    numbers = [v for v in values if isinstance(v, int | float)]
    return round(float(np.median(numbers)), 3) if numbers else None


def run_once(args: argparse.Namespace, extra: list[str], label: str) -> tuple[int, dict]:
    """One ``windwarden up`` benchmark run with ``extra`` flags; its exit code and figures."""
    folder = Path(tempfile.mkdtemp(prefix="bench-live-"))
    scenario = bench_scenario(args.kind, args.seconds, folder, args.offset, args.scenario)
    token = secrets.token_urlsafe(16)
    port = free_port()
    run_id = f"bench-{args.kind}{label}-{time.strftime('%Y%m%d-%H%M%S')}"
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
        *extra,
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


def role_of(cmdline: list[str]) -> str | None:
    """Which of ``up``'s children a command line is: plant, supervisor, shard <turbines>, coordinator, api, router,
    rerun (the recorder and any viewer)."""
    if cmdline and Path(cmdline[0]).name.startswith("rerun"):
        return "rerun"
    if "windwarden.cli" not in cmdline:
        return None
    args = cmdline[cmdline.index("windwarden.cli") + 1 :]
    if not args:
        return None
    if args[0] == "supervise":
        return f"shard {args[args.index('--turbines') + 1]}" if "--turbines" in args else "supervisor"
    return {"coordinate": "coordinator"}.get(args[0], args[0])


def sample_cpu(up: subprocess.Popen, into: dict[int, tuple[str, float]], every_s: float = 0.25) -> None:
    """CPU seconds (user + system) of each of ``up``'s children, read every ``every_s`` while it lives: unlike
    latencies, a process's own CPU time hardly depends on what else the machine runs (the last ``every_s`` of a
    child's life is not seen)."""
    try:
        parent = psutil.Process(up.pid)
    except psutil.NoSuchProcess:
        return
    while up.poll() is None:
        try:
            children = parent.children(recursive=True)
        except psutil.NoSuchProcess:
            return
        for child in children:
            try:
                role = role_of(child.cmdline())
                cpu = child.cpu_times()
            except (psutil.NoSuchProcess, psutil.AccessDenied):
                continue
            if role is not None:
                into[child.pid] = (role, cpu.user + cpu.system)
        time.sleep(every_s)


def cpu_by_role(samples: dict[int, tuple[str, float]], seconds: float) -> dict[str, float]:
    """CPU seconds per wall second of the run, per role (several processes of a role added up)."""
    total: dict[str, float] = {}
    for role, cpu in samples.values():
        total[role] = total.get(role, 0.0) + cpu
    return {role: round(cpu / seconds, 3) for role, cpu in sorted(total.items())}


def report(args: argparse.Namespace, up: subprocess.Popen, port: int, token: str, run_id: str) -> tuple[int, dict]:
    figures: dict[str, object] = {}
    load: list[float] = []
    cpu: dict[int, tuple[str, float]] = {}
    threading.Thread(target=sample_load, args=(up, load), daemon=True).start()
    threading.Thread(target=sample_cpu, args=(up, cpu), daemon=True).start()
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
    up_info = json.loads((run_dir / "up.json").read_text())
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
        "access_control": up_info.get("access_control"),
        "router_refused": up_info.get("router_refused"),
        "nice": args.nice,
        "cpu_per_wall_s": cpu_by_role(cpu, args.seconds / args.speed),
        "load_average_1min": {
            "min": min(load, default=None),
            "mean": sum(load) / max(len(load), 1),
            "max": max(load, default=None),
            "cpus": os.cpu_count(),
        },
    }
    print(json.dumps(figures, indent=2))
    (run_dir / "bench.json").write_text(json.dumps(figures, indent=2) + "\n")
    return code, figures


if __name__ == "__main__":
    sys.exit(main())
