"""``WakeTables.waked_per_turbine``: the wakes of a farm whose turbines see different wind directions (a direction
carried across the farm by the wind, ``plant_sim.farm.direction``), against ``waked`` and against a pair-by-pair
reference written from the table arrays."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from plant_sim.farm.floris_wakes import WakeSettings, wake_tables
from wwcore.layout import SEED001_LAYOUT
from wwcore.turbine_params import BENCHMARK

D = 2.0 * BENCHMARK.radius
SECTOR = (255.0, 290.0)


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    cache = tmp_path_factory.mktemp("wakes")
    layout = SEED001_LAYOUT.resolve(D)
    return {
        m: wake_tables(layout, WakeSettings(model=m, sector_deg=SECTOR), BENCHMARK, cache) for m in ("gauss", "jensen")
    }


def inputs(seed: int, farms: int = 4):
    rng = np.random.default_rng(seed)
    directions = rng.uniform(262.0, 283.0, (farms, 9))  # several table intervals within each farm
    thrust = rng.uniform(0.2, 0.88, (farms, 9, 9))
    free = rng.uniform(6.0, 14.0, (farms, 9))
    return directions, thrust, free


@pytest.mark.parametrize("model", ["gauss", "jensen"])
def test_one_direction_per_farm_is_waked_bit_for_bit(tables, model):
    directions, thrust, free = inputs(1)
    one = directions[:, :1].repeat(9, axis=1)
    for pair_thrust in (thrust, thrust[:, :, 0]):
        got = tables[model].waked_per_turbine(one, pair_thrust, free)
        want = tables[model].waked(directions[:, 0], pair_thrust, free)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


@pytest.mark.parametrize("model", ["gauss", "jensen"])
def test_each_turbine_is_combined_at_its_own_direction(tables, model):
    """Column j is ``waked`` at θ_j: exactly for Jensen (its deficit does not depend on TI) and for every
    turbulence intensity; for Gauss the deficits of i use TI_i at i's own direction, checked by the reference."""
    t = tables[model]
    directions, thrust, free = inputs(2)
    speed, ti = t.waked_per_turbine(directions, thrust, free)
    for f in range(len(directions)):
        for j in range(9):
            v, tj = t.waked(directions[f, j], thrust[f], free[f])
            assert ti[f, j] == pytest.approx(tj[j], rel=0, abs=1e-12)
            if model == "jensen":
                assert speed[f, j] == pytest.approx(v[j], rel=0, abs=1e-12)


def reference(t, directions, thrust, free):
    """Pair by pair, from the table arrays: each (i, j) weighted between the two table directions around θ_j,
    bilinear in s = 1 − √(1 − C_T) and TI_i (scipy's grid interpolator), TI_i from ``waked`` at θ_i."""
    s_grid = 1.0 - np.sqrt(1.0 - t.thrust_grid)
    out = np.empty_like(free)
    for f in range(directions.shape[0]):
        ti_own = np.array([t.waked(directions[f, i], thrust[f], free[f])[1][i] for i in range(9)])
        for j in range(9):
            x = (directions[f, j] % 360.0) / t.direction_step_deg
            k0 = int(np.floor(x))
            deficit = np.zeros(9)
            for k, w in ((k0, 1.0 - (x - k0)), ((k0 + 1) % t.n_directions, x - k0)):
                for e in range(t.bin_start[k], t.bin_start[k + 1]):
                    if t.downstream[e] != j:
                        continue
                    i = t.upstream[e]
                    s = 1.0 - np.sqrt(1.0 - min(max(thrust[f, i, j], 0.0), t.thrust_grid[-1]))
                    table = t.deficit[e].astype(float)
                    if len(t.ti_grid) == 1:
                        value = np.interp(s, s_grid, table[:, 0])
                    else:
                        grid = RegularGridInterpolator((s_grid, t.ti_grid), table)
                        value = grid([[s, min(ti_own[i], t.ti_grid[-1])]])[0]
                    deficit[i] += w * value
            out[f, j] = free[f, j] * (1.0 - np.sqrt(np.sum(deficit**2)))
    return out


@pytest.mark.parametrize("model", ["gauss", "jensen"])
def test_per_turbine_wakes_equal_a_pair_by_pair_reference(tables, model):
    directions, thrust, free = inputs(3, farms=2)
    speed, _ = tables[model].waked_per_turbine(directions, thrust, free)
    np.testing.assert_allclose(speed, reference(tables[model], directions, thrust, free), rtol=0, atol=1e-9)
    assert np.ptp(speed / free) > 0.1  # waked, and differently


def test_bad_inputs_are_refused_and_change_nothing(tables):
    t = tables["gauss"]
    directions, thrust, free = inputs(4, farms=2)
    before = [a.copy() for a in (directions, thrust, free)]
    with pytest.raises(ValueError, match=r"direction_deg must have shape \(farms, 9\)"):
        t.waked_per_turbine(directions[:, :8], thrust, free)
    with pytest.raises(ValueError, match=r"thrust must have shape \(2, 9\) or \(2, 9, 9\)"):
        t.waked_per_turbine(directions, thrust[:1], free)
    outside = directions.copy()
    outside[1, 4] = 300.0
    with pytest.raises(ValueError, match="outside the sector the wake tables cover"):
        t.waked_per_turbine(outside, thrust, free)
    for a, b in zip((directions, thrust, free), before, strict=True):
        np.testing.assert_array_equal(a, b)
