"""The dispatch over a held subset (a sharded supervisor's lost shard, ``FarmSample.held``): the held turbines are
fixed producers at the references they were sent last, eqs. (18)–(26) and the trim run over the served ones, on
hand-computed numbers; with nothing held every reference is the one the dispatch gives without the field."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from service.farm.dispatch import Dispatch
from service.farm.interfaces import FarmContext, FarmDiagnosis, FarmSample
from service.farm.power_loop import PIFarmController
from service.farm.supervisor import FarmSupervisor
from tests.farm.test_dispatch import MW, _faulty
from tests.farm.test_dispatch import _dispatch as dispatch_with
from tests.farm.test_dispatch import _sample as dispatch_sample
from wwcore.farm_frames import CANCEL_3P_MODE, DEBRIS_MODE
from wwcore.scenario.farm import FarmPlant
from wwcore.turbine_params import BENCHMARK as P

SITE = FarmPlant().site()
HELD = np.array([False] * 4 + [True] * 5)  # turbines 5-9: the shard 5-9 lost
AVAIL = [1.0, 2.0, 3.0, 1.0, 2.0, 3.0, 1.0, 2.0, 3.0]  # MW, P_avail stubbed
# t = 0.1 s: all served, 12 MW demand → eq. (18): P_avail/18 · 12
FIRST = np.array(AVAIL) / 18.0 * 12.0
HELD_MW = FIRST[4:].sum()  # 11/18 · 12 = 7.333 MW: the references turbines 5-9 keep
SERVED_AVAIL = sum(AVAIL[:4])  # 7 MW


def _sample(demand_mw: float, held: np.ndarray | None = None, power_mw: np.ndarray | None = None) -> FarmSample:
    return dispatch_sample(demand_mw, power_mw, held)


def _dispatch(avail_mw: list[float] = AVAIL, trim: tuple[float, float] = (0.0, 0.0)) -> Dispatch:
    return dispatch_with(avail_mw, trim=trim)


def _held_dispatch() -> tuple[Dispatch, np.ndarray]:
    """A dispatch that has sent its first references (W) with every turbine served, and those references."""
    d = _dispatch()
    first = d.step(_sample(12.0), _faulty()).copy()
    assert first / MW == pytest.approx(FIRST)
    return d, first


def test_the_served_turbines_make_up_the_demand_the_held_ones_keep_their_references():
    d, first = _held_dispatch()
    refs_w = d.step(_sample(14.0, HELD), _faulty())
    assert np.array_equal(refs_w[4:], first[4:])  # exactly the references the plant keeps
    refs = refs_w / MW
    # the demand less the held references, 14 − 7.333 = 6.667 MW < Σ_S P_avail = 7 MW: (18) over turbines 1-4
    served = 14.0 - HELD_MW
    assert refs[:4] == pytest.approx(np.array(AVAIL[:4]) / SERVED_AVAIL * served)
    assert refs.sum() == pytest.approx(14.0)  # the farm's total reference meets the demand
    assert d.held_power[0] / MW == pytest.approx(HELD_MW) and d.served_demand[0] / MW == pytest.approx(served)
    # sharing over every turbine, as if the held ones followed, would have missed the demand by 1.2 MW
    assert sum(AVAIL[:4]) / 18.0 * 14.0 + HELD_MW == pytest.approx(12.78, abs=0.01)
    # and again at the next sample: the held turbines still at the references the plant keeps
    refs_w = d.step(_sample(13.0, HELD), _faulty())
    assert refs_w[:4] / MW == pytest.approx(np.array(AVAIL[:4]) / SERVED_AVAIL * (13.0 - HELD_MW))
    assert np.array_equal(refs_w[4:], first[4:]) and refs_w.sum() / MW == pytest.approx(13.0)


def test_beyond_what_the_served_turbines_can_make_they_run_at_rated_and_the_farm_is_bounded_by_their_power():
    d, first = _held_dispatch()
    refs = d.step(_sample(16.0, HELD), _faulty())
    # 16 − 7.333 = 8.667 MW > Σ_S P_avail = 7 MW: (19) off for the served, each asked for rated (all it has)
    assert np.all(refs[:4] == P.rated_power) and np.array_equal(refs[4:], first[4:])
    made = np.minimum(refs / MW, AVAIL).sum()  # what the turbines can make: Σ_S P_avail + Σ_H P_held
    assert made == pytest.approx(SERVED_AVAIL + HELD_MW) and made < 16.0
    assert d.served_demand[0] / MW == pytest.approx(16.0 - HELD_MW)


def test_a_demand_below_the_held_references_leaves_the_served_turbines_nothing():
    d, first = _held_dispatch()
    refs = d.step(_sample(6.0, HELD), _faulty())
    assert np.all(refs[:4] == 0.0) and np.array_equal(refs[4:], first[4:]) and d.served_demand[0] == 0.0


def test_eqs_25_26_derate_within_the_served_turbines_and_never_a_held_one():
    d = _dispatch([2.0] * 9)
    d.step(_sample(12.0), _faulty())  # 4/3 MW each
    held = np.array([False] * 5 + [True] * 4)  # turbines 6-9 held at 4/3 MW: 5.333 MW
    first = d.p_ref.copy()
    refs_w = d.step(_sample(12.0, held), _faulty(t2=2, t7=2))
    assert np.array_equal(refs_w[5:], first[5:])
    refs = refs_w / MW
    # served demand 6.667, Σ_S P_avail = 10 → P_over = 3.333 (25); t2: max(2 − 3.333, 0.05) = 0.05 (26); t7 held
    served = 12.0 - 4 * 4.0 / 3.0
    total = 4 * 2.0 + 0.05
    assert refs[1] == pytest.approx(0.05 / total * served)
    assert refs[[0, 2, 3, 4]] == pytest.approx(np.full(4, 2.0 / total * served))
    assert refs.sum() == pytest.approx(12.0)


def test_eqs_23_24_debris_within_the_served_turbines():
    d = _dispatch([2.0] * 9)
    d.step(_sample(12.0), _faulty())
    held = np.array([False] * 5 + [True] * 4)
    refs = d.step(_sample(12.0, held), _faulty(t1=0)) / MW
    served = 12.0 - 4 * 4.0 / 3.0  # 6.667 MW over Σ = 4·2 + 0.97·2 = 9.94
    assert refs[0] == pytest.approx(1.94 / 9.94 * served / 0.97)
    assert refs[1:5] == pytest.approx(np.full(4, 2.0 / 9.94 * served))
    assert 0.97 * refs[0] + refs[1:5].sum() == pytest.approx(served)


def test_the_trim_answers_the_served_turbines_power_error_only():
    kp, ki = 0.5, 0.5
    d = _dispatch(trim=(kp, ki))
    first = d.step(_sample(12.0, power_mw=FIRST), _faulty()).copy()  # the farm makes its demand: e ≈ 0
    served = 14.0 - HELD_MW
    power = np.concatenate([np.array(AVAIL[:4]) / SERVED_AVAIL * served - 0.1, np.full(5, 9.0)])  # 0.4 MW short
    refs = d.step(_sample(14.0, HELD, power), _faulty())
    e = 0.4 / served  # the held turbines' (stale) power is not counted, their references are
    u = kp * e + ki * e * 0.1
    assert refs[:4] / MW == pytest.approx(np.array(AVAIL[:4]) / SERVED_AVAIL * served * (1.0 + u))
    assert np.array_equal(refs[4:], first[4:])


def test_when_the_shard_rejoins_the_dispatch_shares_over_every_turbine_again():
    d, _ = _held_dispatch()
    d.step(_sample(14.0, HELD), _faulty())
    refs = d.step(_sample(15.0), _faulty()) / MW
    assert refs == pytest.approx(np.array(AVAIL) / 18.0 * 15.0)
    assert d.held_power[0] == 0.0 and d.served_demand[0] == 15.0 * MW


def test_nothing_held_is_the_dispatch_without_the_field_value_for_value():
    """A sample whose ``held`` is all False gives the same references, modes and trims, bit for bit, as one without
    it (the coordinator passes None then; the mask's arithmetic must be exact too)."""
    none, no_row = _dispatch(trim=(0.5, 0.5)), _dispatch(trim=(0.5, 0.5))
    rng = np.random.default_rng(1)
    faults = [_faulty(), _faulty(t1=0), _faulty(t2=2, t5=1), _faulty(t3=1)]
    for k in range(40):
        power = rng.uniform(0.5, 2.0, 9)
        demand = float(rng.uniform(6.0, 20.0))
        a = none.step(_sample(demand, None, power), faults[k % 4])
        b = no_row.step(_sample(demand, np.zeros(9, dtype=bool), power), faults[k % 4])
        assert np.array_equal(a, b) and np.array_equal(none.mode, no_row.mode)
    assert np.array_equal(none.power_trim.integral, no_row.power_trim.integral)


def test_the_pi_shares_the_demand_less_the_held_references_over_the_served_turbines():
    pi = PIFarmController(context=FarmContext(SITE, 9), options={"pi_kp": 0.0, "pi_ki": 0.0})
    first = pi.step(_sample(9.0), _faulty()).copy()
    assert first == pytest.approx(np.full(9, 1.0 * MW))
    refs = pi.step(_sample(11.0, HELD), _faulty())
    assert refs[:4] / MW == pytest.approx(np.full(4, (11.0 - 5.0) / 4)) and np.array_equal(refs[4:], first[4:])


class _Unaware:
    """A farm controller plug-in written before ``held``: new references, modes, trims and ripple every step."""

    def __init__(self, n: int):
        self.n, self.calls = n, 0
        self.mode = np.zeros(n, dtype=np.int8)
        self.pitch_trim = np.zeros((n, 3))
        self.ripple_power = np.zeros(n, dtype=complex)
        self.ripple_rate = np.zeros(n)

    def step(self, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        self.calls += 1
        self.mode = np.full(self.n, DEBRIS_MODE if self.calls == 1 else CANCEL_3P_MODE, dtype=np.int8)
        self.pitch_trim = np.full((self.n, 3), 0.1 * self.calls)
        self.ripple_power = np.full(self.n, 1e4 * self.calls + 0j)
        self.ripple_rate = np.full(self.n, 4.0)
        return np.full(self.n, 1e5 * self.calls)


def test_the_supervisor_keeps_the_held_rows_whatever_a_controller_unaware_of_them_returns():
    sup = FarmSupervisor(SITE, 9, detector="none", controller="none")
    sup.controller = _Unaware(9)
    diagnosis = FarmDiagnosis(np.zeros((9, 3), dtype=bool), np.zeros((9, 3)), np.full((9, 3), np.nan))
    first = sup.decide(9, _sample(12.0), diagnosis)
    sup.drain_events()
    refs = sup.decide(19, replace(_sample(12.0), held=HELD), diagnosis)
    assert np.array_equal(refs.power_ref, [2e5] * 4 + [1e5] * 5)
    assert np.array_equal(sup.mode, [CANCEL_3P_MODE] * 4 + [DEBRIS_MODE] * 5)
    assert np.array_equal(refs.pitch_trim[4:], first.pitch_trim[4:]) and np.all(refs.pitch_trim[:4] == 0.2)
    assert np.all(refs.ripple_power[4:] == 0) and np.all(refs.ripple_rate[4:] == 0) and np.all(refs.ripple_rate[:4])
    assert not refs.cancel_3p[4:].any() and refs.cancel_3p[:4].all()
    dispatch_events = [e for e in sup.drain_events() if e.type.value == "dispatch"]
    assert sorted(e.turbine for e in dispatch_events) == [1, 2, 3, 4]  # no mode change made up for a held turbine
