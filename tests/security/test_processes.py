"""Process faults under ``windwarden up`` (real time ×1, no API, the Rerun recorder running):

* ``kill -9`` of the plant: ``up`` stops the rest and leaves a scorecard marked partial, scored over the stretch
  the plant ran, and its last message lists only files that exist; ``windwarden finalize`` gives the same card;
* SIGKILL of ``up``: no child is left (router, plant, supervisor, recorder, web viewer; checked by process group), the
  watchdog closes the run (scorecard, a recording that passes ``rerun rrd verify``) and exits;
* SIGTERM of ``up``: the same, by ``up`` itself (exit 130).
Events written before the kill are intact.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from tests.live.helpers import wait_for
from windwarden.evaluation.scoring_policy import TURBINE
from windwarden.live.finalize import verify_recording
from windwarden.live.router import free_port
from windwarden.live.runfolder import EVENTS, LIVE, RECORDING, SCORECARD, read_events
from windwarden.live.watchdog import process_start

SCENARIO = """
name = "processes"
duration_s = 300.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0]]
[[faults]]
name = "generator sensor 2 stuck"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 1.0
end_s = 300.0
"""


def start_up(tmp_path: Path, *extra: str) -> tuple[subprocess.Popen, Path]:
    (tmp_path / "s.toml").write_text(SCENARIO)
    env = {k: v for k, v in os.environ.items() if not k.startswith("WINDWARDEN_")} | {"RERUN_ANALYTICS": "0"}
    argv = [
        sys.executable,
        "-m",
        "windwarden.cli",
        "up",
        str(tmp_path / "s.toml"),
        "--no-api",
        "--runs-root",
        str(tmp_path / "runs"),
        "--run-id",
        "r",
        "--listen",
        f"tcp/127.0.0.1:{free_port()}",
        *extra,
    ]
    up = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return up, tmp_path / "runs" / "r"


def running(run_dir: Path, after_s: float = 2.0) -> bool:
    """The plant has checkpointed past ``after_s`` and the supervisor has flagged the stuck sensor."""
    try:
        live = json.loads((run_dir / LIVE).read_text())
    except (OSError, ValueError):
        return False
    detected = any(e.type.value == "detection" for e in read_events(run_dir / EVENTS))
    return live["timing"]["t"] > after_s and detected


def pids(run_dir: Path) -> dict[str, int]:
    return json.loads((run_dir / "up.json").read_text())["pids"]


def groups_alive(groups: set[int]) -> list[int]:
    """Processes in any of the process groups ``groups`` (each child of up leads its own)."""
    alive = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] != "Z" and int(fields[2]) in groups:
            alive.append(int(entry.name))
    return alive


def test_kill_9_of_the_plant_leaves_a_partial_scorecard(tmp_path):
    up, run_dir = start_up(tmp_path)
    try:
        # past the turbine's scoring warm-up, so the partial card scores the fault window
        assert wait_for(lambda: running(run_dir, after_s=TURBINE.warmup_s + 3.0), 120), "the run did not get going"
        before = (run_dir / EVENTS).read_bytes()
        os.kill(pids(run_dir)["plant"], signal.SIGKILL)
        output, _ = up.communicate(timeout=120)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait(30)
    assert up.returncode == 1, output
    card = json.loads((run_dir / SCORECARD).read_text())
    live = card["live"]
    assert live["partial"] and not live["completed"] and "partial" in live["note"]
    assert 3.0 < live["scored_s"] < 300.0 and live["ticks"] > 200
    assert [(f["detected_pct"], f["isolated_pct"]) for f in card["faults"]] == [(100.0, 100.0)]
    assert (run_dir / EVENTS).read_bytes().startswith(before)
    last = output.strip().splitlines()
    line = next(x for x in reversed(last) if x.startswith("run folder"))
    assert "scorecard.json" in line and "events.jsonl" in line and "recording.rrd (verified)" in line, output
    assert verify_recording(run_dir / RECORDING)
    again = subprocess.run(
        [sys.executable, "-m", "windwarden.cli", "finalize", str(run_dir)], capture_output=True, text=True, timeout=120
    )
    assert again.returncode == 0 and "partial" in again.stdout, again.stdout + again.stderr
    assert json.loads((run_dir / SCORECARD).read_text()) == card


def test_sigkill_of_up_orphans_nothing(tmp_path):
    up, run_dir = start_up(tmp_path, "--viewer", "web")
    try:
        assert wait_for(lambda: running(run_dir), 90), "the run did not get going"
        children = pids(run_dir)
        watchdog = json.loads((run_dir / "up.json").read_text())["watchdog_pid"]
        assert set(children) == {"router", "recorder", "viewer", "supervisor", "plant"}
        watchdog_start = process_start(watchdog)
        before = (run_dir / EVENTS).read_bytes()
        up.kill()
        up.wait(10)
        groups = set(children.values())
        assert wait_for(lambda: not groups_alive(groups), 40), groups_alive(groups)
        assert wait_for(lambda: process_start(watchdog) != watchdog_start, 120), "the watchdog did not finish"
    finally:
        if up.poll() is None:
            up.kill()
    summary = json.loads((run_dir / "up.json").read_text())
    assert summary["finalized_by"] == "watchdog" and summary["recording_verified"]
    assert verify_recording(run_dir / RECORDING)
    card = json.loads((run_dir / SCORECARD).read_text())
    assert not card["live"]["completed"] and card["live"]["scored_s"] > 2.0
    assert (run_dir / EVENTS).read_bytes().startswith(before)


def test_sigterm_of_up_stops_every_child(tmp_path):
    up, run_dir = start_up(tmp_path)
    try:
        assert wait_for(lambda: running(run_dir), 90), "the run did not get going"
        children = pids(run_dir)
        up.terminate()
        output, _ = up.communicate(timeout=120)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait(30)
    assert up.returncode == 130, output
    assert not groups_alive(set(children.values()))
    summary = json.loads((run_dir / "up.json").read_text())
    assert summary["recording_verified"] and "finalized_by" not in summary
    card = json.loads((run_dir / SCORECARD).read_text())
    assert not card["live"]["completed"] and not card["live"]["partial"]  # stopped, not killed: a whole card
    assert card["live"]["ticks_without_refs"] < card["live"]["ticks"]  # counts only ticks that ran
