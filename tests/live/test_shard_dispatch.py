"""The dispatch with a lost shard, in lockstep over Zenoh: while shard 5-9 is lost its turbines keep the references
the plant holds for them and the served turbines 1-4 take up the rest of the demand (the farm's references add up
to it as the demand moves); when the shard rejoins the dispatch shares over every turbine again."""

from __future__ import annotations

import numpy as np
import pytest

from service.farm.supervisor import FarmSupervisor
from tests.live.helpers import scenario, wait_for
from tests.live.shard_helpers import sharded_farm
from windwarden.live.runfolder import EVENTS, read_events

# the open-loop dispatch (no farm-power trim), so that the references of a sample add up to its demand exactly; the
# demand follows the wind (a ramp) every 2 s, so it moves while the shard is lost
HELD_SCENARIO = """
name = "farm-shard-held-dispatch"
duration_s = 30.0
[plant]
kind = "farm"
[plant.demand]
mode = "available_fraction"
fraction = 0.8
averaging_s = 5.0
update_s = 2.0
[wind]
mean = [[0.0, 10.0], [30.0, 12.0]]
[supervisor.params]
trim_kp = 0.0
trim_ki = 0.0
"""
A, B = (1, 2, 3, 4), (5, 6, 7, 8, 9)
SERVED, HELD = slice(0, 4), slice(4, 9)
KILL_AT_S, RESTART_AT_S = 5.0, 20.0  # farm time


class Decisions:
    """Every farm sample the coordinator decides: its demand, the rows it held, the references, P_avail (20)–(22)."""

    def __init__(self) -> None:
        self.rows: list[dict] = []

    def wrap(self, decide):
        def recorded(sup: FarmSupervisor, tick, sample, diagnosis):
            refs = decide(sup, tick, sample, diagnosis)
            held = np.zeros(len(refs.power_ref), bool) if sample.held is None else sample.held.copy()
            self.rows.append(
                {
                    "tick": tick,
                    "demand": float(sample.demand[0]),
                    "held": held,
                    "refs": refs.power_ref.copy(),
                    "avail": sup.controller.p_avail.copy(),
                }
            )
            return refs

        return recorded


def test_the_served_turbines_take_up_a_lost_shards_part_and_the_full_set_returns_on_rejoin(tmp_path, monkeypatch):
    decisions = Decisions()
    monkeypatch.setattr(FarmSupervisor, "decide", decisions.wrap(FarmSupervisor.decide))  # the coordinator's
    run_dir = tmp_path / "run"
    with sharded_farm(scenario(HELD_SCENARIO), run_dir, [A, B], mode="lockstep", seed=5) as (sharded, nodes):
        plant, coordinator = nodes.plant, sharded.coordinator
        assert wait_for(lambda: plant.plant.t >= KILL_AT_S, 60), "the farm did not start"
        sharded.kill(1)
        assert wait_for(lambda: "5-9" in coordinator.status()["lost_shards"], 30), coordinator.status()
        assert wait_for(lambda: any(d["held"].any() for d in decisions.rows[-1:]), 30)
        status = coordinator.status()
        held_refs = plant.latest_refs["power_ref"][HELD].copy()  # what the plant keeps for turbines 5-9
        assert wait_for(lambda: plant.plant.t >= RESTART_AT_S, 60)
        assert np.array_equal(plant.latest_refs["power_ref"][HELD], held_refs)  # still, while lost
        sharded.restart(1)
        assert wait_for(lambda: coordinator.status()["shards_rejoined"] == 1, 30), coordinator.status()
        assert nodes.wait(120) == 0
        assert not sharded.errors

    rows = decisions.rows
    held = [i for i, d in enumerate(rows) if d["held"].any()]
    assert held and all(list(np.flatnonzero(rows[i]["held"]) + 1) == list(B) for i in held)
    first, last = held[0], held[-1]
    assert held == list(range(first, last + 1))  # one spell, from the loss to the rejoin
    before = rows[first - 1]
    assert not before["held"].any()

    # the held turbines: fixed at the references the dispatch sent them last, and the plant applies those (or,
    # if the shard died before passing the last ones on, the ones of the sample before)
    kept = before["refs"][HELD]
    assert all(np.array_equal(rows[i]["refs"][HELD], kept) for i in held)
    assert any(np.array_equal(held_refs, rows[i]["refs"][HELD]) for i in (first - 1, first - 2))
    # ... and the status and the event say so
    assert status["held_turbines"] == list(B) and status["held_power_ref_w"] == pytest.approx(kept.sum(), rel=1e-12)
    assert 0.0 < status["served_demand_w"] < max(d["demand"] for d in rows)
    (lost,) = [e for e in read_events(run_dir / EVENTS) if e.type.value == "liveliness" and not e.detail["alive"]]
    assert lost.detail["held_turbines"] == list(B) and lost.detail["held_power_ref_w"] == pytest.approx(list(kept))

    # the served turbines take up the rest of the demand: the farm's references add up to it, sample by sample
    demand = np.array([rows[i]["demand"] for i in held])
    served_refs = np.array([rows[i]["refs"][SERVED].sum() for i in held])
    served_avail = np.array([rows[i]["avail"][SERVED].sum() for i in held])
    feasible = demand - kept.sum() < served_avail
    assert feasible.all(), "the served turbines could not make up the held ones' part: the test shows nothing"
    assert served_refs + kept.sum() == pytest.approx(demand, rel=1e-9)
    assert demand.max() - demand.min() > 0.2e6  # the demand moved while the shard was lost
    # sharing over every turbine, as the dispatch did before, would have missed it by the held turbines' difference
    shared = np.array([rows[i]["refs"].sum() for i in held])  # (the same sums, computed apart)
    all_avail = np.array([rows[i]["avail"].sum() for i in held])
    old_total = demand * served_avail / all_avail + kept.sum()
    assert np.abs(old_total - demand).max() > 0.05e6 and shared == pytest.approx(demand, rel=1e-9)

    # after the rejoin: eq. (18) over every turbine again, the turbines 5-9 following new references
    after = rows[last + 1 :]
    assert len(after) > 20 and not any(d["held"].any() for d in after)
    for d in after:
        assert d["refs"] == pytest.approx(d["avail"] / d["avail"].sum() * d["demand"], rel=1e-9)
    assert not np.array_equal(after[-1]["refs"][HELD], kept)
    print(
        f"held {len(held)} farm samples, demand {demand.min() / 1e6:.3f}–{demand.max() / 1e6:.3f} MW, turbines 5-9 "
        f"held at {kept.sum() / 1e6:.3f} MW; references short of the demand by at most "
        f"{np.abs(old_total - demand).max() / 1e6:.3f} MW if shared over every turbine, "
        f"{np.abs(shared - demand).max():.1e} W as dispatched"
    )
