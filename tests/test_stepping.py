"""The batch loop (``wwcore.stepping.run_ticks``): the step contract's order, each hook at its point of the tick, and
the same plant and supervisor numbers as the four calls written out by hand."""

from __future__ import annotations

import numpy as np

from windwarden.kinds import RunInfo, kind_for
from wwcore.scenario import load_scenario
from wwcore.stepping import run_ticks


class _Plant:
    def __init__(self, log: list):
        self.log, self.k = log, 0

    def measure(self):
        self.log.append(("measure", self.k))
        return self.k

    def control(self, refs):
        self.log.append(("control", self.k, refs))

    def advance(self):
        self.log.append(("advance", self.k))
        self.k += 1


class _Supervisor:
    def __init__(self, log: list):
        self.log = log

    def step(self, frame):
        self.log.append(("step", frame))
        return f"refs{frame}"


def test_the_order_of_one_tick_and_its_hooks():
    log: list = []
    last = run_ticks(
        _Plant(log),
        _Supervisor(log),
        range(2),
        "given",
        before=lambda k, refs: log.append(("before", k, refs)),
        controlled=lambda k, frame: log.append(("controlled", k, frame)),
        stepped=lambda k, frame, refs: log.append(("stepped", k, frame, refs)),
        advanced=lambda k: log.append(("advanced", k)),
    )
    assert last == "refs1"
    assert log == [
        ("before", 0, "given"),
        ("measure", 0),
        ("control", 0, "given"),  # tick 0 is controlled with the refs it was given
        ("controlled", 0, 0),
        ("step", 0),
        ("stepped", 0, 0, "refs0"),
        ("advance", 0),
        ("advanced", 0),
        ("before", 1, "refs0"),
        ("measure", 1),
        ("control", 1, "refs0"),  # tick 1 with the refs computed from tick 0
        ("controlled", 1, 1),
        ("step", 1),
        ("stepped", 1, 1, "refs1"),
        ("advance", 1),
        ("advanced", 1),
    ]


def test_run_ticks_equals_the_loop_written_out():
    """Two copies of the demo turbine (same seed) for 3 s: the loop by hand and ``run_ticks`` give the same estimates
    and events, bit for bit."""
    scenario = load_scenario("demo").model_copy(update={"duration_s": 3.0})
    kind = kind_for("turbine")

    def build():
        plant = kind.make_plant(scenario, 4)
        return plant, kind.make_supervisor(RunInfo.of(scenario, kind.turbines(plant), plant.dt))

    ticks = round(scenario.duration_s / 0.01)
    plant, supervisor = build()
    by_hand, refs = [], None
    for _ in range(ticks):
        frame = plant.measure()
        plant.control(refs)
        refs = supervisor.step(frame)
        by_hand.append(supervisor.estimates.wind.copy())
        plant.advance()
    hand_events = plant.drain_events() + supervisor.drain_events()

    plant2, supervisor2 = build()
    looped: list = []
    run_ticks(
        plant2, supervisor2, range(ticks), stepped=lambda k, f, r: looped.append(supervisor2.estimates.wind.copy())
    )
    np.testing.assert_array_equal(np.array(looped), np.array(by_hand))
    assert plant2.drain_events() + supervisor2.drain_events() == hand_events
    assert plant2.k == plant.k == ticks
