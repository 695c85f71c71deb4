"""The one-line status of ``windwarden up``: what it shows from the plant's status and the events, its width, in
place on a terminal and plain lines at most every ``every_s`` elsewhere (a fake clock, no sleeps)."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from windwarden.live.status_line import RunStatus, StatusDisplay, format_status
from wwcore.events import Event, EventType

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)


def _event(t: float, kind: EventType, turbine: int = 1, target: str = "omega_r_m1", label: str = "f") -> Event:
    detail = {"label": label} if kind in (EventType.FAULT_INJECTED, EventType.FAULT_CLEARED) else {}
    return Event(t=t, type=kind, turbine=turbine, target=target, detail=detail)


def test_the_line_shows_time_progress_real_time_factor_faults_and_flags():
    status = RunStatus()
    status.on_status({"t": 123.45, "duration_s": 600.0, "real_time_factor": 0.998, "state": "running"})
    status.on_event(_event(100.0, EventType.FAULT_INJECTED))
    status.on_event(_event(100.2, EventType.DETECTION))
    status.on_event(_event(100.3, EventType.DETECTION, turbine=2, target="beta_1_m1"))
    status.on_event(_event(101.0, EventType.RECOVERY, turbine=2, target="beta_1_m1"))
    line = format_status(status)
    assert line == ("t 123.5/600 s (21 %)  ×1.00 real time  faults 1: T1 omega_r_m1  flags 1 (2 raised): T1 omega_r_m1")


def test_a_cleared_fault_leaves_the_line_and_the_state_shows_when_not_running():
    status = RunStatus()
    status.on_event(_event(5.0, EventType.FAULT_INJECTED, label="a"))
    status.on_event(_event(6.0, EventType.FAULT_INJECTED, label="b"))
    status.on_event(_event(7.0, EventType.FAULT_CLEARED, label="a"))
    assert len(status.faults) == 1
    status.on_status({"t": 8.0, "duration_s": None, "real_time_factor": None, "state": "ended"})
    assert format_status(status) == "t 8.0 s  ended  faults 1: T1 omega_r_m1  flags 0 (0 raised)"


def test_before_any_status_the_line_has_no_time_and_bad_fields_are_ignored():
    status = RunStatus()
    assert format_status(status) == "t –  faults 0  flags 0 (0 raised)"
    status.on_status({"t": "soon", "real_time_factor": True, "state": 3})
    assert status.t is None and status.real_time_factor is None and status.state == "starting"


def test_many_faults_are_counted_and_the_line_fits_its_width():
    status = RunStatus()
    status.on_status({"t": 1.0, "duration_s": 10.0, "real_time_factor": 1.0})
    for turbine in range(1, 10):
        status.on_event(_event(1.0, EventType.FAULT_INJECTED, turbine=turbine, target="drivetrain"))
        status.on_event(_event(1.0, EventType.DETECTION, turbine=turbine, target="drivetrain"))
    full = format_status(status, width=1000)
    assert "faults 9: T1 drivetrain, T2 drivetrain, T3 drivetrain +6" in full
    assert "flags 9 (9 raised)" in full
    for width in (40, 80, 100):
        line = format_status(status, width)
        assert len(line) <= width and line.endswith("…")


def _console(terminal: bool) -> tuple[Console, io.StringIO]:
    out = io.StringIO()
    return Console(file=out, force_terminal=terminal, width=100, color_system=None), out


def test_off_a_terminal_a_plain_line_comes_every_every_s_and_nothing_between():
    console, out = _console(terminal=False)
    now = [0.0]
    display = StatusDisplay(console, every_s=10.0, clock=lambda: now[0])
    assert not display.in_place
    display.start()
    display.on_status({"t": 2.0, "duration_s": 20.0, "real_time_factor": 1.0, "state": "running"})
    for step in range(1, 251):  # 25 s of the watch loop's 0.1 s ticks
        now[0] = step * 0.1
        display.tick()
    display.stop()
    lines = out.getvalue().splitlines()
    assert lines == ["t 2.0/20 s (10 %)  ×1.00 real time  faults 0  flags 0 (0 raised)"] * 2
    display.tick()  # stopped: nothing more
    assert out.getvalue().splitlines() == lines


def test_plain_lines_leave_the_other_output_parseable():
    """The report's last line still starts with ``run folder`` and the event lines stay whole."""
    console, out = _console(terminal=False)
    now = [0.0]
    display = StatusDisplay(console, every_s=10.0, clock=lambda: now[0])
    display.start()
    console.print("t=  100.20 s  detection        T1 omega_r_m1 ")
    now[0] = 10.0
    display.tick()
    display.stop()
    console.print("run folder runs/x: scorecard.json, events.jsonl")
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("t=  100.20 s  detection")
    assert lines[1].startswith("t –  faults 0")
    assert next(x for x in reversed(lines) if x.startswith("run folder")) == lines[-1]


def test_on_a_terminal_the_line_is_live_and_gone_when_it_stops():
    console, out = _console(terminal=True)
    display = StatusDisplay(console, clock=lambda: 0.0)
    assert display.in_place
    display.on_event(_event(3.0, EventType.FAULT_INJECTED))
    display.start()
    display.tick()  # in place: tick prints nothing of its own
    display.stop()
    text = out.getvalue()
    assert "faults 1: T1 omega_r_m1" in text  # rendered by Live
    assert "\x1b[2K" in text  # and erased (transient) when it stopped
