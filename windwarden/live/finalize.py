"""End of a live run: the scorecard from ``events.jsonl`` (same scoring code as batch) and the recording closed.

``finalize_scorecard`` may run more than once (the plant at its end, ``up`` once every child has stopped, so a
late event is still counted); each run rewrites ``scorecard.json`` from the files alone.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from windwarden.live.adapters import adapter_for
from windwarden.live.runfolder import EVENTS, LIVE, RECORDING, RUN, SCENARIO, SCORECARD, read_events, write_json
from wwcore.scenario import FaultSpec, load_scenario


def finalize_scorecard(run_dir: Path) -> dict[str, Any] | None:
    """Compute and write ``scorecard.json``; None when the plant left no ``live.json`` (it never ran)."""
    live_path = run_dir / LIVE
    if not live_path.exists():
        return None
    live = json.loads(live_path.read_text())
    run = json.loads((run_dir / RUN).read_text())
    scenario = load_scenario(run_dir / SCENARIO)
    adapter = adapter_for(scenario.plant.kind)
    faults = [FaultSpec.model_validate(f) for f in live["effective_faults"]]
    events = read_events(run_dir / EVENTS)
    card = adapter.scorecard(scenario, int(run["seed"]), faults, events, live["metrics"])
    timing = live["timing"]
    card["live"] = {
        "run_id": run["run_id"],
        "mode": timing["mode"],
        "speed": timing["speed"],
        "completed": live["completed"],
        "ticks": live["ticks_run"],
        "overruns": timing["overruns"],
        "overrun_pct": timing["overrun_pct"],
        "resyncs": timing["resyncs"],
        "real_time_factor": timing["real_time_factor"],
        "latency": timing["latency"],
        "dropped": timing["dropped"],
        "ticks_without_refs": live["metrics"].get("ticks_without_refs"),
        "events": len(events),
    }
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
