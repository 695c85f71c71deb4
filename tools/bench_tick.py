"""What a tick of the live system costs in CPU: the plant node and the supervisor node, each in its own process
behind a router, as ``windwarden up`` runs them, stepped in lockstep (as fast as they go; ``--mode realtime``: at
×1) for N simulated seconds of a farm scenario (Horns Rev 1's 80 turbines by default).

Each node is the real one (``PlantNode``, ``SupervisorNode``, built as ``windwarden plant`` and ``windwarden
supervise`` build them), with its Rerun display sinking to a file instead of the recorder's proxy (``--no-display``:
none). A thread of each process reads, once the node has passed its warm-up ticks and again at the end, the
process's CPU time (every thread: the node's loop, Zenoh's threads and the callbacks they run, Rerun's sink) and the
CPU time of the node's main thread (its loop alone), and divides by the ticks between. CPU time depends on the
machine's other work far less than latency does, but not at all is too much to say (caches, memory bandwidth): on
the shared machine two runs of one tree differ by up to ±15 %, so compare interleaved runs.

``--baseline TREE`` runs the same nodes from another source tree (an export of another commit: ``git archive
COMMIT | tar -x -C DIR``) interleaved with this one (baseline, this, this, baseline, …, ``--repeat`` pairs) and
reports the medians, the ratio this / baseline of the medians and of each pair: a before/after comparison from one
run, both sides under the same load. In lockstep it also compares the two runs' recordings row by row (every entity
and value the plant and the supervisor logged, but the loop's timing): a change that only cuts CPU leaves them
identical (in real time the numbers depend on when each refs frame arrived, so they are not compared).
``--profile`` runs each node's loop under cProfile, timed by the main thread's CPU clock (waits and other threads
left out), and prints per tick the cumulative time of the parts of its tick (the profiler slows Python calls, numpy
calls more than plain bytecode: read the shares, not the milliseconds).

    .venv/bin/python tools/bench_tick.py --seconds 30
    git archive main | tar -x -C ../base && .venv/bin/python tools/bench_tick.py --baseline ../base --repeat 4
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
from typing import Any

import numpy as np

HERE = Path(__file__).resolve()
TREE = HERE.parent.parent
TIMELINE = "sim_time"
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
def threads_cpu() -> dict[str, tuple[str, float]]:
    """Each thread of this process: its name and CPU seconds (user + system, at the kernel's clock-tick
    resolution), from ``/proc/self/task``; names with their numbers dropped (Zenoh's ``rx-3`` → ``rx``)."""
    out = {}
    tick = os.sysconf("SC_CLK_TCK")
    for task in Path("/proc/self/task").iterdir():
        try:
            stat = (task / "stat").read_text()
        except OSError:
            continue
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        out[task.name] = (re.sub(r"[-_ ]?\d+$", "", name), (int(fields[11]) + int(fields[12])) / tick)
    return out


class CpuMeter:
    """The process's and the main thread's CPU time once ``count()`` reaches ``warm``, and at ``finish``."""

    def __init__(self, count: Callable[[], int], warm: int):
        self.count = count
        self.warm = warm
        self.start: dict[str, float] | None = None
        self._main = time.pthread_getcpuclockid(threading.main_thread().ident)
        self._done = threading.Event()
        threading.Thread(target=self._watch, daemon=True).start()

    def sample(self, n: int) -> dict[str, Any]:
        return {
            "n": n,
            "process_s": time.process_time(),
            "main_s": time.clock_gettime(self._main),
            "wall_s": time.perf_counter(),
            "threads": threads_cpu(),
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
        by_name: dict[str, float] = {}
        for tid, (name, cpu) in end["threads"].items():
            before = self.start["threads"].get(tid, (name, 0.0))[1]
            by_name[name] = by_name.get(name, 0.0) + cpu - before
        return {
            "threads_ms_per_tick": {
                name: round(1e3 * cpu / ticks, 4) for name, cpu in sorted(by_name.items(), key=lambda kv: -kv[1]) if cpu
            },
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
    display = None
    if not args.no_display:
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
        node = SupervisorNode(session, settings, None if args.no_display else display)
        meter = CpuMeter(lambda: node.frames, WARM_TICKS)
        try:
            code = run_node(node.run, folder / "supervisor.prof" if args.profile else None)
            figures = meter.finish(node.frames)
        finally:
            node.close()
    return figures | {"exit_code": code, "dropped": node.drops.as_dict()}


def parts_worker(args: argparse.Namespace) -> dict:
    """The parts of the two nodes' ticks in one process without the network: the calls ``PlantNode.run`` and
    ``SupervisorNode._on_frame`` make per tick, in their order, each timed by this thread's CPU clock (no profiler,
    so no call is slowed). What this leaves out: the Zenoh puts and their threads, the queues and waits between the
    nodes, the status messages."""
    import tempfile as temporary

    from dashboards.live import LiveRecording
    from windwarden.commands.live import truncated
    from windwarden.kinds import RunInfo, kind_for
    from windwarden.live.guard import FrameSequencer, RefsGuard
    from windwarden.live.mailbox import TickMailbox
    from wwcore.scenario import load_scenario
    from wwcore.wire import DropCounter

    scenario = truncated(load_scenario(args.scenario), args.seconds)
    kind = kind_for(scenario.plant.kind)
    plant = kind.make_plant(scenario, args.seed)
    turbines = kind.turbines(plant)
    info = RunInfo.of(scenario, turbines, float(plant.dt), "bench-tick", "lockstep", 1.0, run_key=1)
    supervisor = kind.make_supervisor(info)
    drops = DropCounter()
    guard = RefsGuard(kind.refs, 10, drops)
    refs_box = TickMailbox(kind.refs, turbines, drops, "refs", guard.window)
    sensors_box = TickMailbox(kind.sensors, turbines, drops, "sensors")
    sequencer = FrameSequencer(50, drops, lambda run: None, lambda tick: False)
    sequencer.start(1)
    score = kind.score(scenario, round(scenario.duration_s / plant.dt), plant.dt)
    folder = Path(temporary.mkdtemp(prefix="bench-tick-parts-"))
    every = 10
    plant_display = LiveRecording(
        kind.kind, "plant", "parts", path=str(folder / "p.rrd"), n_turbines=len(turbines), plant_section=scenario.plant
    )
    supervisor_display = LiveRecording(kind.kind, "supervisor", "parts", path=str(folder / "s.rrd"), n_turbines=80)
    ticks = round(args.seconds / plant.dt)
    cost: dict[str, dict[str, np.ndarray]] = {"plant": {}, "supervisor": {}}
    clock = time.thread_time_ns

    def timed(role: str, part: str, k: int, call: Callable[..., Any], *args: Any) -> Any:
        started = clock()
        out = call(*args)
        cost[role].setdefault(part, np.zeros(ticks))[k] += clock() - started
        return out

    def sensor_frame(frame: Any) -> tuple[np.ndarray, bytes]:
        records = kind.frame_records(frame, turbines)
        records["run"] = 1
        return records, kind.sensors.encode_frame(records)

    def plant_rows(frame: Any, records: np.ndarray) -> None:
        truth = kind.truth_records(plant, frame, turbines)
        kind.truth.encode_frame(truth)
        plant_display.plant_rows(records, truth)

    def refs_frame(step: Any) -> tuple[np.ndarray, bytes]:
        out = kind.refs_records(step, supervisor, turbines)
        return out, kind.refs.encode_frame(out)

    def supervisor_rows(records: np.ndarray, out: np.ndarray) -> None:
        supervisor_display.supervisor_rows(records, out, lambda: kind.status(supervisor, out, turbines))

    refs_payload, latest = None, None
    for k in range(ticks):
        guard.k = k
        if refs_payload is not None:  # on a Zenoh thread in the node; here before the tick that drains it
            timed("plant", "refs frame in (decode, assemble)", k, refs_box.put, refs_payload)
        for arrival in timed("plant", "refs taken (range check)", k, refs_box.drain):
            verdict = timed("plant", "refs taken (range check)", k, guard.judge, arrival.tick, arrival.records, k)
            score.on_refs(arrival.tick, arrival.records)
            if verdict == "take":
                latest = arrival.records
        refs = None if latest is None else timed("plant", "refs to controller", k, kind.refs_from_records, latest)
        timed("plant", "display send", k, plant_display.pump)
        frame = timed("plant", "measure", k, plant.measure)
        records, payload = timed("plant", "sensor frame out (encode)", k, sensor_frame, frame)
        timed("plant", "control", k, plant.control, refs)
        timed("plant", "score", k, score.on_tick, k, frame, plant)
        if k % every == 0:
            timed("plant", "truth and display rows (10 Hz)", k, plant_rows, frame, records)
        timed("plant", "advance", k, plant.advance)
        plant.drain_events()
        timed("supervisor", "sensor frame in (decode, assemble)", k, sensors_box.put, payload)
        for arrival in timed("supervisor", "sensor frame in (decode, assemble)", k, sensors_box.drain):
            timed("supervisor", "frame decision", k, sequencer.decide, arrival.records)
            frame_in = timed("supervisor", "frame to supervisor", k, kind.frame_from_records, arrival.records)
            step = timed("supervisor", "supervisor.step", k, supervisor.step, frame_in)
            supervisor.drain_events()
            out, refs_payload = timed("supervisor", "refs frame out (encode)", k, refs_frame, step)
            sequencer.stepped(k)
            if k % every == 0:
                timed("supervisor", "display rows (10 Hz)", k, supervisor_rows, arrival.records, out)
            timed("supervisor", "display send", k, supervisor_display.pump)
    warm = slice(WARM_TICKS, None)
    report: dict[str, Any] = {"ticks": ticks - WARM_TICKS, "dropped": drops.as_dict()}
    for role, parts in cost.items():
        total = sum(parts.values())[warm] / 1e6
        report[role] = {
            "ms_per_tick": round(float(total.mean()), 4),
            "p99_ms": round(float(np.percentile(total, 99)), 3),
            "parts_ms_per_tick": {
                part: round(float(v[warm].mean()) / 1e6, 4)
                for part, v in sorted(parts.items(), key=lambda kv: -kv[1][warm].mean())
            },
        }
    plant_display.close()
    supervisor_display.close()
    return report


def worker(args: argparse.Namespace) -> int:
    import windwarden

    figures = {"plant": plant_worker, "supervisor": supervisor_worker, "parts": parts_worker}[args.worker](args)
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
        worker_argv += ["--no-display"] if args.no_display else []
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


def run_parts(tree: Path, args: argparse.Namespace, folder: Path) -> dict:
    """``parts_worker`` in a process of ``tree``; its figures."""
    folder.mkdir(parents=True)
    env = os.environ | {"PYTHONPATH": str(tree)}
    env.pop("WINDWARDEN_STEP_BACKEND", None)
    argv = [sys.executable, str(HERE), "--worker", "parts", "--folder", str(folder), "--scenario", args.scenario]
    argv += ["--seconds", str(args.seconds), "--seed", str(args.seed)]
    subprocess.run(argv, cwd=tree, env=env, check=True, timeout=1800)
    return json.loads((folder / "parts.json").read_text())


def parts_summary(runs: list[dict]) -> dict:
    out: dict[str, Any] = {}
    for role in ("plant", "supervisor"):
        names = list(runs[-1][role]["parts_ms_per_tick"])
        out[role] = {
            "ms_per_tick": round(float(np.median([r[role]["ms_per_tick"] for r in runs])), 4),
            "runs": [r[role]["ms_per_tick"] for r in runs],
            "parts_ms_per_tick": {
                name: round(float(np.median([r[role]["parts_ms_per_tick"].get(name, 0.0) for r in runs])), 4)
                for name in names
            },
        }
    return out


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


TIMING_ENTITIES = ("/run/timing",)  # the loop's own latency figures: wall clock, different in every run


def recording_rows(path: Path) -> dict[tuple[str, str], list[tuple[int, str]]]:
    """Every (entity, component) of a recording with its rows (time ns, value), sorted; the timing entity left
    out. Two runs whose live numbers are the same bit for bit have the same rows (the chunking may differ)."""
    from rerun.chunk import RrdReader

    rows: dict[tuple[str, str], list[tuple[int, str]]] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if TIMELINE not in batch.schema.names or chunk.entity_path in TIMING_ENTITIES:
            continue
        times = batch.column(TIMELINE).cast("int64").to_pylist()
        for name in batch.schema.names:
            if ":" in name and not name.startswith("rerun"):
                values = [repr(v) for v in batch.column(name).to_pylist()]
                rows.setdefault((chunk.entity_path, name), []).extend(zip(times, values, strict=True))
    return {key: sorted(value) for key, value in rows.items()}


def same_recordings(a: Path, b: Path) -> dict[str, object]:
    """Whether two runs' recordings (plant and supervisor) hold the same rows, bit for bit (``recording_rows``)."""
    out: dict[str, object] = {}
    for role in ("plant", "supervisor"):
        rows_a, rows_b = recording_rows(a / f"{role}.rrd"), recording_rows(b / f"{role}.rrd")
        differ = sorted({k for k in rows_a.keys() | rows_b.keys() if rows_a.get(k) != rows_b.get(k)})
        out[role] = {
            "rows": sum(len(v) for v in rows_a.values()),
            "identical": not differ,
            **({"differ": [f"{e} {c}" for e, c in differ[:10]]} if differ else {}),
        }
    return out


def parts_main(args: argparse.Namespace, trees: dict[str, Path], out: Path) -> int:
    """``--parts``: the in-process parts of each tree's tick, interleaved; medians and ratios this / baseline."""
    results: dict[str, list[dict]] = {name: [] for name in trees}
    for i in range(max(args.repeat, 1)):
        for name in list(trees) if i % 2 == 0 else list(reversed(trees)):
            print(f"parts {i + 1}: {name} ({trees[name]})", file=sys.stderr, flush=True)
            results[name].append(run_parts(trees[name], args, out / f"parts-{name}-{i}"))
    report: dict[str, Any] = {"scenario": args.scenario, "seconds": args.seconds, "warm_up_ticks": WARM_TICKS}
    report |= {name: parts_summary(runs) for name, runs in results.items()}
    if "baseline" in results:
        base, this = report["baseline"], report["this"]
        report["ratio_this_to_baseline"] = {
            role: {
                "ms_per_tick": round(this[role]["ms_per_tick"] / base[role]["ms_per_tick"], 3),
                "per_repetition": [
                    round(t[role]["ms_per_tick"] / b[role]["ms_per_tick"], 3)
                    for b, t in zip(results["baseline"], results["this"], strict=True)
                ],
                "parts": {
                    part: round(ms / base[role]["parts_ms_per_tick"][part], 3)
                    for part, ms in this[role]["parts_ms_per_tick"].items()
                    if base[role]["parts_ms_per_tick"].get(part)
                },
            }
            for role in ("plant", "supervisor")
        }
    print(json.dumps(report, indent=2))
    return 0


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
    parser.add_argument("--no-display", action="store_true", help="nodes without their Rerun display")
    parser.add_argument(
        "--parts", action="store_true", help="instead: the parts of both nodes' ticks in one process, no network"
    )
    parser.add_argument("--out", type=Path, default=None, help="folder for the runs (default: a temporary one)")
    parser.add_argument("--worker", choices=("plant", "supervisor", "parts"), help=argparse.SUPPRESS)
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
    if args.parts:
        return parts_main(args, trees, out)
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
        report["ratio_per_repetition"] = {
            role: [
                round(t[role]["process_ms_per_tick"] / b[role]["process_ms_per_tick"], 3)
                for b, t in zip(results["baseline"], results["this"], strict=True)
            ]
            for role in ("plant", "supervisor")
        }
        report["ratio_this_to_baseline"] = {
            role: {f: round(this[role][f] / base[role][f], 3) for f in FIGURES} for role in ("plant", "supervisor")
        } | {"both_process": round(this["both_process_ms_per_tick"] / base["both_process_ms_per_tick"], 3)}
        if not args.no_display and args.mode == "lockstep":  # the live numbers, run by run (in real time they
            # depend on when each refs frame arrived: two runs of one tree differ too)
            report["recordings_identical_to_baseline"] = [
                same_recordings(out / f"baseline-{i}", out / f"this-{i}") for i in range(max(args.repeat, 1))
            ]
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
