"""How a frozen speed reading is isolated (docs/turbine.md): flagged without the generator-speed arbitration, a
healthy witness over the isolation level waited out and a second fault still joined within the patience, and its one
look at the rotor-speed pair handing a disagreement to the pair's sequential test (decisions N-31, N-42). The shared
set-up is ``tests/test_turbine_isolation.py``'s."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.turbine.fdi import SpeedSensorFDI
from tests.test_turbine_isolation import (
    BIT,
    DESIGN,
    SPEED_SIGMA,
    _fdi,
    _first_flag,
    _healthy_chi2,
    _healthy_history,
    _readings,
    _seen_at_once,
    _settled_fdi,
)
from wwcore.turbine_params import BENCHMARK as P


def test_a_reading_frozen_near_the_truth_is_flagged_without_arbitration():
    """ω_g,m2 frozen at the true speed: no residual sees it and the observers using it stay consistent, so the
    arbitration between the two generator-speed sensors could take seconds; a frozen reading is a fault whatever
    its value, and it is flagged on the tick the frozen test fires."""
    fdi = _fdi()
    rng, x_hat = _healthy_history(fdi, 6)
    frozen_value = 1.2 * P.N_g
    flagged_at = None
    for k in range(200):
        y = _readings(rng)
        y[0, 3] = frozen_value
        fdi.step(y, _healthy_chi2(fdi), x_hat)
        if fdi.flagged[0] and flagged_at is None:
            flagged_at = k
            assert fdi.flagged[0] == BIT["omega_g_m2"]
    assert flagged_at == fdi.s.frozen_ticks - 1
    assert fdi.flagged[0] == BIT["omega_g_m2"], "kept while frozen"


def _frozen_rotor_speed_run(fdi: SpeedSensorFDI, witness_stat) -> list[int]:
    """ω_r,m1 frozen at the true speed from tick 0 (the frozen test fires on tick ``frozen_ticks`` − 1), the other
    readings healthy; ``witness_stat(k, j)`` is observer j's χ² on tick k, or None for its mean. Returns the flagged
    bitmask of every tick."""
    rng, x_hat = _healthy_history(fdi, 12)
    masks = []
    for k in range(15):
        stat = _healthy_chi2(fdi)
        for j in range(DESIGN.n_isolating):
            value = witness_stat(k, j)
            if value is not None:
                stat[0, j] = value
        y = _readings(rng)
        y[0, 0] = 1.2
        fdi.step(y, stat, x_hat)
        masks.append(int(fdi.flagged[0]))
    return masks


def test_a_frozen_reading_waits_out_a_healthy_witness_over_the_isolation_level():
    """docs/turbine.md's shipped one-rotor window: on the tick the frozen test fires, observer 6-r1g2 (a witness of
    ω_r,m1 alone that never reads it) is just over the isolation level, under the detection level, so ω_r,m1 alone
    is consistent at the detection level only. Deciding on that tick flagged the smallest superset consistent at the
    isolation level with the smallest own statistic (observer 4's, ω_r,m1 + ω_r,m2, under 6-r1g1's as there), the
    healthy ω_r,m2 with it; the decision waits instead, and the next ticks name ω_r,m1 alone."""
    fdi = _fdi()
    j = DESIGN.names.index("6-r1g2")
    deciding = fdi.s.frozen_ticks - 1
    spike = 1.05 * fdi.h_isolate[j]
    assert spike < fdi.h_detect[j] and spike + 3 * fdi._rank[j] < fdi.h_window[j], "under the detection level"
    on_deciding_tick = {j: spike, DESIGN.names.index("6-r1g1"): 2.0}
    k, first = _first_flag(
        _frozen_rotor_speed_run(fdi, lambda k, i: on_deciding_tick.get(i) if k == deciding else None)
    )
    assert first == BIT["omega_r_m1"], "the first flag names the frozen sensor alone"
    assert deciding < k <= deciding + fdi.s.isolation_delay + fdi.s.isolation_patience


@pytest.mark.parametrize("level", ["between", "beyond"])
def test_a_frozen_reading_with_a_second_fault_is_flagged_with_it_within_the_patience(level):
    """ω_r,m1 frozen and ω_r,m2 faulty: every observer reading ω_r,m2 has its window sum between the isolation and
    the detection levels from the deciding tick on ("between"; ω_r,m1 alone is consistent at the detection level,
    so the decision waits, up to ``isolation_delay`` + ``isolation_patience`` ticks), or each tick beyond the
    detection level ("beyond": ω_r,m1 alone is rejected, nothing to wait for). Both are flagged together first."""
    fdi = _fdi()
    w = fdi.s.window
    per_tick = {
        "between": 0.5 * (fdi.h_isolate_window + fdi.h_window) / w,
        "beyond": 1.5 * fdi.h_detect,
    }[level]

    def stat(k, j):
        return None if "omega_r_m2" in DESIGN.left_out[j] else per_tick[j]

    k, first = _first_flag(_frozen_rotor_speed_run(fdi, stat))
    assert first == BIT["omega_r_m1"] | BIT["omega_r_m2"]
    bound = fdi.s.frozen_ticks - 1 + (fdi.s.isolation_delay + fdi.s.isolation_patience if level == "between" else 0)
    assert k <= bound


def _frozen_generator_first_flags(rows: int, seed: int, rotor_excursion: float, rotor_bias: float) -> tuple:
    """ω_g,m2 frozen far from the truth from tick 0 (every observer using it sees it at once, χ² = 10⁴; detected on
    tick 0, the frozen test fires on tick ``frozen_ticks`` − 1), as the mismatch set's one-generator window
    (docs/turbine.md, seed 84506); the rotor-speed readings white, ω_r,m1 and ω_r,m2 apart by ± ``rotor_excursion``
    σ_r on each tick up to the frozen test's (noise, as run 2's; white after), ω_r,m2 biased by ``rotor_bias`` σ_r
    throughout.
    Returns each row's first flagged bitmask (0: none within 60 ticks) and the tick of it."""
    fdi, rng, x_hat, truth, healthy = _settled_fdi(rows, seed)
    stat = _seen_at_once(healthy, "omega_g_m2")
    first, tick = np.zeros(rows, dtype=np.int64), np.full(rows, -1)
    for k in range(60):
        y = truth + SPEED_SIGMA * rng.standard_normal((rows, 4))
        if k < fdi.s.frozen_ticks:
            apart = np.array([1.0, -1.0]) * rotor_excursion + 1e-3 * rng.standard_normal((rows, 2))  # not frozen
            y[:, :2] = truth[0] + apart * SPEED_SIGMA[:2]
        y[:, 1] += rotor_bias * SPEED_SIGMA[1]
        y[:, 3] = 100.0
        fdi.step(y, stat, x_hat)
        tick = np.where((first == 0) & (fdi.flagged != 0), k, tick)
        first = np.where(first == 0, fdi.flagged, first)
    return fdi, first, tick


def test_a_frozen_reading_s_one_look_at_a_healthy_pair_joins_no_rotor_speed_sensor_alone():
    """The mismatch set's one wrong first flag (docs/turbine.md, seed 84506, run 2): the healthy rotor-speed pair's
    difference ran 2.9 σ of the plant's on the isolation's first two ticks by chance, so the frozen sensor's one
    look at it passed (z > 3.29 ŝ, probability α_iso a look) and ω_r,m1 joined the frozen ω_g,m2. A look that passes
    now hands the decision to the sequential test against the trusted encoder, which joins a healthy sensor in a
    few hundredths of such rows (a simulation of the walk: 0.02–0.05) and else names ω_g,m2 alone once every Λ_s
    ≤ −ln(1/α_confirm). Synthetic, 200 rows: the pair apart by ±1.6 σ_r on each of the first three ticks (z = 3.92 at
    the frozen test's tick, Λ_s = 3.7 < 8.3): the one look alone joined ω_r,m1 in every row on that tick; now
    ω_g,m2 alone first in 196 (≥ 95 %), 5–37 ticks later (the walk back to Λ_s ≤ −3)."""
    fdi, first, tick = _frozen_generator_first_flags(200, 81, 1.6, 0.0)
    deciding = fdi.s.frozen_ticks - 1
    z = 2 * 1.6 / math.sqrt(2) * math.sqrt(fdi.s.frozen_ticks)
    assert z > fdi.arbiter.parity_level  # 3.92 > 3.29: the look passes
    assert (first & BIT["omega_g_m2"] != 0).all(), np.unique(first, return_counts=True)
    alone = int((first == BIT["omega_g_m2"]).sum())
    assert alone >= 0.95 * 200, np.unique(first, return_counts=True)
    assert (tick[first == BIT["omega_g_m2"]] > deciding).all()  # waited on the sequential test


def test_a_frozen_reading_s_partner_rotor_speed_fault_still_joins_on_the_frozen_test_s_tick():
    """A 4 σ_r bias on ω_r,m2 beside the frozen ω_g,m2: the one look passes and the sequential test against ω_g,m1
    is already beyond its level on the frozen test's tick (Λ_2 ≈ 1.25 × 12 − 3 × 0.78 = 12.7 ≥ 8.3), so both are
    flagged first on that tick, as the one look alone flagged two sensors there; the test names ω_r,m2, where the
    one look alone took the rotor-speed sensor whose explanation's own observer had the smaller statistic (with
    every observer at its mean, ω_r,m1 in every row)."""
    fdi, first, tick = _frozen_generator_first_flags(200, 82, 0.0, 4.0)
    both = int(((first == BIT["omega_g_m2"] | BIT["omega_r_m2"]) & (tick == fdi.s.frozen_ticks - 1)).sum())
    assert both >= 0.97 * 200, np.unique(first, return_counts=True)
