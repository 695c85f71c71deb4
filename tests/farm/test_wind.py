"""The farm's wind: propagation delay d/v̄ (eq. (3)), the Jensen deficit, thrust from momentum theory."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plant_sim.farm.wind import (
    FarmWindField,
    MastSeries,
    jensen_deficit,
    static_row_winds,
    thrust_from_power_coefficient,
)
from plant_sim.turbine.plant import row_streams
from service.farm.signals import MastDelays
from tests.farm.conftest import farm_spec, wind
from wwcore.scenario.farm import FARM_DT_S
from wwcore.turbine_params import BENCHMARK


def test_jensen_deficit_closed_form():
    # C_T = 0.75: 1 − √0.25 = 0.5; x = 805 m, k = 0.05, R = 57.5: (57.5/97.75)² = 0.34602…
    d = jensen_deficit(np.array(0.75), 805.0, 57.5, 0.05)
    assert d == pytest.approx(0.5 * (57.5 / (57.5 + 0.05 * 805.0)) ** 2, rel=1e-12)
    assert jensen_deficit(np.array(0.0), 805.0, 57.5, 0.05) == 0.0
    assert jensen_deficit(np.array(0.75), 0.0, 57.5, 0.05) == pytest.approx(0.5)


def test_thrust_from_momentum_theory():
    # a = 1/3 gives Betz: C_p = 16/27, C_T = 8/9; a = 0.1: C_p = 4·0.1·0.81 = 0.324, C_T = 0.36
    assert thrust_from_power_coefficient(np.array(16.0 / 27.0)) == pytest.approx(8.0 / 9.0, rel=1e-6)
    assert thrust_from_power_coefficient(np.array(0.324)) == pytest.approx(0.36, rel=1e-5)
    assert thrust_from_power_coefficient(np.array(-0.1)) == 0.0


def test_front_row_sees_the_free_stream_and_rows_behind_less():
    v = static_row_winds(farm_spec(1), BENCHMARK, np.array([8.0]))[0]
    assert v[0] == 8.0 and v[1] < v[0] and v[2] < v[1]
    no_wakes = static_row_winds(farm_spec(1, wakes=False), BENCHMARK, np.array([8.0]))[0]
    assert np.all(no_wakes == 8.0)


def test_mast_delay_is_distance_over_mean_wind():
    """A step in the mast reading reaches a point d metres away d/v̄ later (supervisor side, eq. (3))."""
    m = MastDelays(1)
    v = 10.0
    for _ in range(200):
        m.step(np.array([v]))
    for j in range(1500):  # a marker sample at j = 0, then back to v
        m.step(np.array([v + (5.0 if j == 0 else 0.0)]))
        seen = m.delayed(np.array([287.5 + 805.0]))[0, 0]
        if seen != v:
            break
    # v̄ ≈ 10 (the 0.5 s marker is filtered out by H(s) = 1/(s+1)), so the marker shows 1092.5/10 s later
    assert j * FARM_DT_S == pytest.approx((287.5 + 805.0) / 10.0, abs=0.15)


def test_plant_rows_see_the_mast_wind_delayed():
    """The plant's row free stream is the true mast wind d_j/v̄ earlier (v̄ the H(s) mean at that time)."""
    spec = farm_spec(1, coherent_ti=0.2, coherent_time_s=20.0)
    mast = MastSeries(spec, wind(10.0), [row_streams(1, 0, 0)[0]], 600.0)
    rngs = [row_streams(1, 0, t)[0] for t in range(1, 10)]
    field = FarmWindField(spec, wind(10.0), BENCHMARK, rngs, mast, np.array([0]), BENCHMARK.dt)
    j = 3000
    free, _ = field.wakes.row_means(j, field.wakes._ct)
    vbar = mast.vbar[0, mast.offset + j]
    for row, d in enumerate(field.wakes.mast_distances):
        expect = np.interp(j * FARM_DT_S - d / vbar, mast.t, mast.v[0])
        assert free[0, row] == pytest.approx(expect, rel=1e-9)
    assert field.wakes.mast_distances[2] - field.wakes.mast_distances[0] == pytest.approx(2 * 805.0)


def test_mast_series_has_the_coherent_turbulence_level():
    spec = farm_spec(1, coherent_ti=0.05, coherent_time_s=60.0)
    mast = MastSeries(spec, wind(10.0), [np.random.default_rng(s) for s in range(20)], 4000.0)
    z = mast.v[:, mast.offset :] / 10.0 - 1.0
    assert z.std() == pytest.approx(0.05, rel=0.15)
    lag = round(60.0 / FARM_DT_S)  # OU correlation e^{−1} at one correlation time
    rho = np.mean(z[:, lag:] * z[:, :-lag]) / z.var()
    assert rho == pytest.approx(math.exp(-1.0), abs=0.12)


def test_row_coherence_shares_the_turbulence_of_a_row():
    from plant_sim.farm import FarmBatch

    def rotor_winds(c: float) -> np.ndarray:
        plant = FarmBatch(farm_spec(1, row_coherence=c, coherent_ti=0.0), wind(10.0), [], seed=1, duration_s=30.0)
        out = []
        for _ in range(3000):
            plant.measure()
            plant.control(None)
            out.append(plant.turbines.true_rotor_wind().copy())
            plant.advance()
        return np.array(out)

    shared, own = rotor_winds(1.0), rotor_winds(0.0)
    # turbines 1 and 4 share a row in case 1: with c = 1 they differ only by their rotors' azimuths
    assert np.std(shared[:, 0] - shared[:, 3]) < 0.2 * np.std(own[:, 0] - own[:, 3])
    assert shared.std(axis=0)[0] == pytest.approx(own.std(axis=0).mean(), rel=0.5)  # same level of turbulence


def test_a_derated_turbine_casts_a_weaker_wake_one_travel_time_later():
    """C_T follows each turbine's own operating point (momentum theory), so derating one turbine raises the wind of
    every row behind its row, x/v̄ later and not before, and leaves its own row and the rows ahead alone."""
    spec = farm_spec(2, coherent_ti=0.0)
    mast = MastSeries(spec, wind(10.0), [row_streams(1, 0, 0)[0]], 600.0)
    rngs = [row_streams(1, 0, t)[0] for t in range(1, 10)]
    field = FarmWindField(spec, wind(10.0), BENCHMARK, rngs, mast, np.array([0]), BENCHMARK.dt)
    steady = field._p_aero.copy()
    derated = steady.copy()
    derated[3] *= 0.8  # turbine 4, in the second row {2, 4} of wind case 2
    omega, pitch = np.full(9, 1.0), np.zeros(9)
    row = spec.row_of()[3]
    lag_s = (
        field.wakes.distances - field.wakes.distances[row]
    ) / 10.0  # travel time behind turbine 4's row at v̄ = 10 m/s
    winds = []
    for j in range(round((lag_s[-1] + 30.0) / FARM_DT_S)):
        field.update(j, steady if j < 10 else derated, omega, pitch)  # the row model reads the power only
        winds.append(field.row_wind[0].copy())
    winds = np.array(winds)
    assert np.array_equal(winds[:, : row + 1], np.repeat(winds[:1, : row + 1], len(winds), axis=0))
    arrive = 10 + round(lag_s[row + 1] / FARM_DT_S)  # the next row; those further back see it through it too
    assert winds[arrive - 2, row + 1] == pytest.approx(winds[0, row + 1], rel=1e-12)
    assert winds[arrive + 2, row + 1] > winds[0, row + 1]
    assert np.all(winds[-1, row + 1 :] > winds[0, row + 1 :] + 0.01)  # m/s
