"""What a tick of the live system costs in CPU: the plant node and the supervisor node, each in its own process
behind a router, as ``windwarden up`` runs them, stepped in lockstep (as fast as they go) for N simulated seconds.

Each node is the real one (``PlantNode``, ``SupervisorNode``, built as ``windwarden plant`` and ``windwarden
supervise`` build them), with its Rerun display sinking to a file instead of the recorder's proxy. A thread of each
process reads, once the node has passed its warm-up ticks and again at the end, the process's CPU time (every
thread: the node's loop, Zenoh's threads and the callbacks they run, Rerun's sink) and the CPU time of the node's
main thread (its loop alone). CPU time counts only what the process itself executes, so unlike the latencies of
``tools/bench_live.py`` it hardly depends on what else the machine runs.

``--baseline TREE`` runs the same nodes from another source tree (an export of another commit: ``git archive
COMMIT | tar -x -C DIR``) interleaved with this one (baseline, this, this, baseline, …, ``--repeat`` pairs), and
reports the medians and the ratio this / baseline of each figure: a before/after comparison from one run, both
sides under the same load. ``--profile`` also runs each node's loop under cProfile and prints, per tick, the
cumulative time of the parts of its tick (the profiler slows Python calls: read the shares, not the milliseconds).

    .venv/bin/python tools/bench_tick.py --seconds 30
    .venv/bin/python tools/bench_tick.py --seconds 30 --baseline ../base --repeat 3
    .venv/bin/python tools/bench_tick.py --seconds 20 --profile
"""

from __future__ import annotations

import argparse
import json
import os
import pstats
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
TREE = HERE.parent.parent
WARM_TICKS = 300  # ticks left out at the start: the first display sends declare the series, caches fill
PARTS = {  # what the profile reports per tick, by function name (those that exist in the tree measured)
    "plant": (
        "_take_refs",
        "_refs_for",
        "_pump_display",
        "measure",
        "frame_records",
        "sensor_frame",
        "encode_frame",
        "put",
        "control",
        "on_tick",
        "truth_records",
        "plant_rows",
        "advance",
        "_publish_status",
        "_lockstep_wait",
    ),
    "supervisor": (
        "drain",
        "_on_frame",
        "decide",
        "frame_from_records",
        "step",
        "refs_records",
        "refs_frame",
        "encode_frame",
        "put",
        "_display",
        "supervisor_rows",
        "pump",
        "_publish_status",
    ),
}


# -- the workers: one node each, in the process of the tree measured ----------------------------------------------
class CpuMeter:
    """The process's and the main thread's CPU time once ``count()`` reaches ``warm``, and at ``finish``."""

    def __init__(self, count: Callable[[], int], warm: int):
        self.count = count
        self.warm = warm
        self.start: dict[str, float] | None = None
        self._main = time.pthread_getcpuclockid(threading.main_thread().ident)
        self._done = threading.Event()
        threading.Thread(target=self._watch, daemon=True).start()

    def sample(self, n: int) -> dict[str, float]:
        return {
            "n": n,
            "process_s": time.process_time(),
            "main_s": time.clock_gettime(self._main),
            "wall_s": time.perf_counter(),
        }

    def _watch(self) -> None:
        while not self._done.is_set():
            n = self.count()
            if n >= self.warm:
                self.start = self.sample(n)
                return
            time.sleep(0.001)

    def finish(self, n: int) -> dict[str, float]:
        self._done.set()
        end = self.sample(n)
        if self.start is None or end["n"] <= self.start["n"]:
            raise SystemExit(f"the node ran {n} ticks, not more than the {self.warm} of the warm-up")
        ticks = end["n"] - self.start["n"]
        return {
            "ticks": ticks,
            "process_ms_per_tick": 1e3 * (end["process_s"] - self.start["process_s"]) / ticks,
            "main_thread_ms_per_tick": 1e3 * (end["main_s"] - self.start["main_s"]) / ticks,
            "wall_ms_per_tick": 1e3 * (end["wall_s"] - self.start["wall_s"]) / ticks,
            "ticks_total": n,
        }


def run_node(run: Callable[[], int], profile: Path | None) -> int:
    if profile is None:
        return run()
    import cProfile

    profiler = cProfile.Profile(time.thread_time)  # CPU time of the node's thread: waits and other threads left out
    try:
        return profiler.runcall(run)
    finally:
        profiler.dump_stats(profile)


def plant_worker(args: argparse.Namespace) -> dict:
    from dashboards.live import LiveRecording
    from windwarden.commands.live import truncated
    from windwarden.live.config import PlantSettings
    from windwarden.live.plant_node import PlantNode
    from windwarden.live.process import zenoh_session
    from wwcore.scenario import load_scenario

    folder = Path(args.folder)
    settings = PlantSettings(
        scenario=args.scenario, seed=args.seed, mode=args.mode, connect=args.connect, run_dir=folder
    )
    scenario = truncated(load_scenario(settings.scenario), args.seconds)
    display = LiveRecording(
        scenario.plant.kind,
        "plant",
        "bench-tick",
        path=str(folder / "plant.rrd"),
        n_turbines=scenario.plant.n_turbines,
        plant_section=scenario.plant,
    )
    with zenoh_session(settings) as session:
        node = PlantNode(session, settings, scenario, "bench-tick", folder, display)
        meter = CpuMeter(lambda: node.k, WARM_TICKS)
        try:
            code = run_node(node.run, folder / "plant.prof" if args.profile else None)
            figures = meter.finish(node.plant.k)
        finally:
            node.close()
    return figures | {"exit_code": code, "dropped": node.drops.as_dict(), "refs_received": node.refs_received}


def supervisor_worker(args: argparse.Namespace) -> dict:
    from dashboards.live import LiveRecording
    from windwarden.live.config import SupervisorSettings
    from windwarden.live.process import zenoh_session
    from windwarden.live.supervisor_node import SupervisorNode

    folder = Path(args.folder)
    settings = SupervisorSettings(connect=args.connect, run_dir=folder, exit_with_run=True, plant_wait_s=120.0)

    def display(info):
        return LiveRecording(
            info.kind, "supervisor", "bench-tick", path=str(folder / "supervisor.rrd"), n_turbines=len(info.turbines)
        )

    with zenoh_session(settings) as session:
        node = SupervisorNode(session, settings, display)
        meter = CpuMeter(lambda: node.frames, WARM_TICKS)
        try:
            code = run_node(node.run, folder / "supervisor.prof" if args.profile else None)
            figures = meter.finish(node.frames)
        finally:
            node.close()
    return figures | {"exit_code": code, "dropped": node.drops.as_dict()}


def worker(args: argparse.Namespace) -> int:
    import windwarden

    figures = (plant_worker if args.worker == "plant" else supervisor_worker)(args)
    figures["source"] = str(Path(windwarden.__file__).parent.parent)
    Path(args.folder, f"{args.worker}.json").write_text(json.dumps(figures, indent=2))
    return 0


# -- the coordinator: a router and the two workers per run, trees interleaved --------------------------------------
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for_port(port: int, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise SystemExit(f"the router did not listen on port {port} within {timeout:.0f} s")


def run_pair(tree: Path, args: argparse.Namespace, folder: Path) -> dict:
    """A router, a supervisor and a plant from ``tree``; the two workers' figures."""
    folder.mkdir(parents=True)
    env = os.environ | {"PYTHONPATH": str(tree), "WINDWARDEN_LOG_LEVEL": "WARNING"}
    env.pop("WINDWARDEN_STEP_BACKEND", None)
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    common = {"cwd": tree, "env": env}
    router = subprocess.Popen(
        [sys.executable, "-m", "windwarden.cli", "router", "--no-acl", "--listen", endpoint], **common
    )
    procs = [router]
    try:
        wait_for_port(port, 30.0)
        worker_argv = [sys.executable, str(HERE), "--connect", endpoint, "--folder", str(folder)]
        worker_argv += ["--scenario", args.scenario, "--seconds", str(args.seconds), "--seed", str(args.seed)]
        worker_argv += ["--mode", args.mode]
        worker_argv += ["--profile"] if args.profile else []
        supervisor = subprocess.Popen([*worker_argv, "--worker", "supervisor"], **common)
        procs.append(supervisor)
        plant = subprocess.Popen([*worker_argv, "--worker", "plant"], **common)
        procs.append(plant)
        timeout = 600.0 + 2.0 * args.seconds * 100 * 0.05
        if plant.wait(timeout) != 0 or supervisor.wait(60.0) != 0:
            raise SystemExit(f"a worker failed (plant {plant.returncode}, supervisor {supervisor.returncode})")
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                proc.terminate()
                proc.wait(30)
    return {role: json.loads((folder / f"{role}.json").read_text()) for role in ("plant", "supervisor")}


FIGURES = ("process_ms_per_tick", "main_thread_ms_per_tick")


def summary(runs: list[dict]) -> dict:
    out: dict[str, dict] = {}
    for role in ("plant", "supervisor"):
        out[role] = {f: round(float(np.median([r[role][f] for r in runs])), 4) for f in (*FIGURES, "wall_ms_per_tick")}
        out[role]["runs"] = [round(r[role]["process_ms_per_tick"], 4) for r in runs]
    out["both_process_ms_per_tick"] = round(
        float(np.median([r["plant"]["process_ms_per_tick"] + r["supervisor"]["process_ms_per_tick"] for r in runs])), 4
    )
    return out


def profile_parts(folder: Path, role: str, ticks: int) -> dict[str, float]:
    """Cumulative ms per tick of the tick's parts (``PARTS``), from the node's profile (startup included in the
    profile, but none of these run at startup but once)."""
    stats = pstats.Stats(str(folder / f"{role}.prof")).stats  # type: ignore[attr-defined]
    parts: dict[str, float] = {}
    for (filename, _, name), (_, _, _, cumulative, _) in stats.items():
        builtin = re.fullmatch(r"<method '(\w+)' of '([\w.]+)' objects>", name) if filename == "~" else None
        base = builtin.group(1) if builtin else name
        if base not in PARTS[role]:
            continue
        where = Path(filename)
        short = f"{builtin.group(2)}.{base}" if builtin else f"{where.parent.name}/{where.stem}.{name}"
        parts[short] = parts.get(short, 0.0) + 1e3 * cumulative / ticks
    return dict(sorted(((k, round(v, 3)) for k, v in parts.items() if v >= 0.005), key=lambda kv: -kv[1]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="farm-hornsrev1", help="shipped scenario or file (default Horns Rev 1)")
    parser.add_argument("--seconds", type=float, default=30.0, help="simulated seconds (100 ticks each)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--mode",
        choices=("lockstep", "realtime"),
        default="lockstep",
        help="lockstep (default: as fast as the nodes go) or realtime at ×1 (the CPU of waiting included)",
    )
    parser.add_argument("--baseline", type=Path, default=None, help="another source tree to compare with")
    parser.add_argument("--repeat", type=int, default=1, help="runs of each tree, interleaved")
    parser.add_argument("--profile", action="store_true", help="also profile each node's loop (cProfile)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the runs (default: a temporary one)")
    parser.add_argument("--worker", choices=("plant", "supervisor"), help=argparse.SUPPRESS)
    parser.add_argument("--connect", help=argparse.SUPPRESS)
    parser.add_argument("--folder", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    if args.seconds * 100 <= 2 * WARM_TICKS:
        parser.error(f"--seconds: more than {2 * WARM_TICKS / 100:g} s, so that most ticks are past the warm-up")
    out = args.out or Path(tempfile.mkdtemp(prefix="bench-tick-"))
    trees = {"this": TREE}
    if args.baseline is not None:
        if not (args.baseline / "windwarden" / "live" / "plant_node.py").is_file():
            parser.error(f"--baseline {args.baseline}: not a windwarden source tree")
        trees = {"baseline": args.baseline.resolve(), "this": TREE}
    results: dict[str, list[dict]] = {name: [] for name in trees}
    for i in range(max(args.repeat, 1)):
        order = list(trees) if i % 2 == 0 else list(reversed(trees))
        for name in order:
            folder = out / f"{name}-{i}"
            print(f"run {i + 1}: {name} ({trees[name]})", file=sys.stderr, flush=True)
            results[name].append(run_pair(trees[name], args, folder))
            if args.profile:
                for role in ("plant", "supervisor"):
                    ticks = results[name][-1][role]["ticks_total"]
                    results[name][-1][role]["profile_ms_per_tick"] = profile_parts(folder, role, ticks)
    report: dict[str, object] = {
        "scenario": args.scenario,
        "seconds": args.seconds,
        "warm_up_ticks": WARM_TICKS,
        "load_average_1min": os.getloadavg()[0],
        "out": str(out),
    }
    for name, runs in results.items():
        report[name] = summary(runs)
        if args.profile:
            report[name]["profile"] = {role: runs[-1][role]["profile_ms_per_tick"] for role in ("plant", "supervisor")}
    if "baseline" in results:
        base, this = report["baseline"], report["this"]
        report["ratio_this_to_baseline"] = {
            role: {f: round(this[role][f] / base[role][f], 3) for f in FIGURES} for role in ("plant", "supervisor")
        } | {"both_process": round(this["both_process_ms_per_tick"] / base["both_process_ms_per_tick"], 3)}
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
