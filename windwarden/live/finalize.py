"""End of a live run: the scorecard from ``events.jsonl`` (same scoring code as batch) and the recording closed.

``finalize_scorecard`` may run more than once (the plant at its end, ``up`` once every child has stopped, so a
late event is still counted; ``windwarden finalize RUN_DIR`` by hand); each run rewrites ``scorecard.json`` from
the files alone. A run that stopped early is scored over the ticks it ran (false-alarm rates, fault windows and
counters cover no tick that never ran). A plant that was killed or crashed leaves no final ``live.json``: the card
is then computed from ``events.jsonl``, the fault listing and the plant's last checkpoint of ``live.json`` (how far
it ran, its timing) and marked ``partial``: detection figures are complete for the stretch that ran, the continuous
metrics the plant accumulated in memory (wind RMSE, reconstruction, farm power) are lost with it.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from windwarden.kinds import kind_for
from windwarden.live.runfolder import (
    EVENTS,
    FAULTS,
    LIVE,
    RECORDING,
    RUN,
    SCENARIO,
    SCORECARD,
    read_events,
    write_json,
)
from wwcore.scenario import FaultSpec, Scenario, load_scenario


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def effective_faults(listing: list[dict[str, Any]]) -> list[FaultSpec]:
    """The faults as they acted, from a ``faults.json`` listing (cancelled ones left out, early clears applied)."""
    out = []
    for entry in listing:
        if entry.get("state") == "cancelled":
            continue
        spec = FaultSpec.model_validate(entry["fault"])
        out.append(spec.model_copy(update={"end_s": entry.get("end_s")}))
    return out


def cut_to(scenario: Scenario, faults: list[FaultSpec], seconds: float) -> tuple[Scenario, list[FaultSpec]]:
    """The scenario and its faults as far as a run went: what started later never acted."""
    acted = [f for f in faults if f.start_s < seconds]
    return scenario.model_copy(update={"duration_s": seconds, "faults": acted}), acted


def finalize_scorecard(run_dir: Path) -> dict[str, Any] | None:
    """Compute and write ``scorecard.json``; None when the plant never started a run there (no ``run.json``)."""
    run = _read_json(run_dir / RUN)
    if run is None or not (run_dir / SCENARIO).exists():
        return None
    live = _read_json(run_dir / LIVE) or {}
    final = bool(live.get("final", "metrics" in live))
    scenario = load_scenario(run_dir / SCENARIO)
    kind = kind_for(scenario.plant.kind)
    events = read_events(run_dir / EVENTS)
    if "effective_faults" in live:
        faults = [FaultSpec.model_validate(f) for f in live["effective_faults"]]
    else:
        faults = effective_faults(_read_json(run_dir / FAULTS) or [])
    timing = live.get("timing") or {}
    dt = float(timing.get("dt") or run.get("dt") or 0.0)
    completed = final and bool(live.get("completed"))
    if live.get("ticks_run") is not None and dt > 0:
        ran_s = live["ticks_run"] * dt
    else:  # killed before its first checkpoint: as far as its events go
        ran_s = max((e.t for e in events), default=0.0)
    scored, faults = (scenario, faults) if completed else cut_to(scenario, faults, min(ran_s, scenario.duration_s))
    metrics = live.get("metrics", {}) if final else {}
    card = kind.scorecard(scored, int(run["seed"]), faults, events, metrics)
    card["live"] = {
        "run_id": run["run_id"],
        "mode": run.get("mode"),
        "speed": run.get("speed"),
        "completed": completed,
        "partial": not final,
        "scored_s": scored.duration_s,
        "ticks": live.get("ticks_run"),
        "overruns": timing.get("overruns"),
        "overrun_pct": timing.get("overrun_pct"),
        "resyncs": timing.get("resyncs"),
        "real_time_factor": timing.get("real_time_factor"),
        "latency": timing.get("latency") or {},
        "dropped": timing.get("dropped", {}),
        "refs_refused": timing.get("refs_refused", {}),
        "ticks_without_refs": metrics.get("ticks_without_refs"),
        "events": len(events),
    }
    if not final:
        card["live"]["note"] = (
            "partial: the plant stopped without finishing its run (killed or crashed); detection figures cover the "
            f"{scored.duration_s:g} s it ran, the continuous metrics it kept in memory are lost"
        )
    write_json(run_dir / SCORECARD, card)
    return card


def rerun_binary() -> str:
    """The ``rerun`` CLI binary that ships with rerun-sdk.

    The ``rerun`` script on the PATH is a Python wrapper that starts this binary as its child; terminating the
    wrapper would leave the binary running, so children are started from the binary itself.
    """
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        binary = Path(spec.origin).parent / "rerun"
        if binary.exists():
            return str(binary)
    here = Path(sys.executable).parent / "rerun"
    return str(here) if here.exists() else (shutil.which("rerun") or "rerun")


def finalize_recording(run_dir: Path, timeout: float = 300.0) -> bool:
    """Compact the streamed recording and give it its footer (``rerun rrd optimize``); True if it verifies.

    The recorder streams into ``recording.rrd`` as data arrives, without a footer; after it has stopped, the
    optimised copy replaces it. The streamed file is kept if optimising fails.
    """
    path = run_dir / RECORDING
    if not path.exists() or path.stat().st_size == 0:
        return False
    tmp = path.with_name("recording.optimized.rrd")
    done = subprocess.run(
        [rerun_binary(), "rrd", "optimize", str(path), "-o", str(tmp)],
        capture_output=True,
        timeout=timeout,
        check=False,
    )
    if done.returncode == 0 and tmp.exists() and verify_recording(tmp):
        tmp.replace(path)
        return True
    tmp.unlink(missing_ok=True)
    return False


def verify_recording(path: Path, footers: bool = True, timeout: float = 120.0) -> bool:
    done = subprocess.run(
        [rerun_binary(), "rrd", "verify", "--check-footers", "true" if footers else "false", str(path)],
        capture_output=True,
        timeout=timeout,
        check=False,
    )
    return done.returncode == 0


def recording_entities(path: Path, timeout: float = 120.0) -> set[str]:
    """Entity paths with data in a recording (``rerun rrd print``), blueprint entities left out."""
    done = subprocess.run(
        [rerun_binary(), "rrd", "print", str(path)], capture_output=True, text=True, timeout=timeout, check=False
    )
    found = set()
    for line in done.stdout.splitlines():
        _, sep, rest = line.partition(" - /")
        if sep:
            found.add("/" + rest.split(" ", 1)[0])
    blueprint = ("/container/", "/view/", "/viewport", "/blueprint_panel", "/selection_panel", "/time_panel")
    return {e for e in found if not e.startswith(blueprint)}
