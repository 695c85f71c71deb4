"""The benchmark wind model (plant_sim.wind): turbulence level and spectrum, shear and tower shadow, batching."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.signal import welch

from plant_sim import wind
from plant_sim.wind import TURBULENCE_SAMPLE_TIME, TurbulenceStreams, WindField, blade_factor, rotor_factor
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import BENCHMARK

P = BENCHMARK
DT = P.dt


def _rngs(*seeds: int) -> list[np.random.Generator]:
    return [np.random.default_rng(s) for s in seeds]


def _turbulence(spec: WindSpec, n: int, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u_p, u_0, u_3), each (n, samples), straight from the 0.05 s streams."""
    streams = TurbulenceStreams(spec, P, _rngs(*range(100, 100 + n)))
    chunks = [streams.next_chunk()[1] for _ in range(round(seconds / TURBULENCE_SAMPLE_TIME) // wind.CHUNK_SAMPLES)]
    return tuple(np.concatenate([c[i] for c in chunks], axis=1) for i in range(3))


def _run(field: WindField, ticks: int, azimuth: np.ndarray) -> dict[str, np.ndarray]:
    """Sample ``ticks`` ticks with the rotor turning at 1.6 rad/s from ``azimuth``; stacked outputs (ticks, n, …)."""
    out: dict[str, list[np.ndarray]] = {"blades": [], "hub": [], "rotor": [], "mean": []}
    for k in range(ticks):
        s = field.sample(k, azimuth + 1.6 * k * DT)
        for name in out:
            out[name].append(np.array(getattr(s, name)))
    return {name: np.stack(v) for name, v in out.items()}


# ---- turbulence ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def turbulence_10ms() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return _turbulence(WindSpec(mean=[(0.0, 10.0)]), n=20, seconds=1200.0)


@pytest.mark.parametrize("speed", [6.0, 10.0, 16.0])
def test_hub_turbulence_std_is_ti_times_mean(speed, turbulence_10ms):
    up = turbulence_10ms[0] if speed == 10.0 else _turbulence(WindSpec(mean=[(0.0, speed)]), 20, 1200.0)[0]
    # 20 × 1200 s against an integral time scale L/(4 v̄) ≤ 25 s: the std is known to about ±4 %
    assert up.std() == pytest.approx(0.12 * speed, rel=0.08)
    assert abs(up.mean()) < 0.05 * 0.12 * speed * 3


def test_rotor_averaging_reduces_turbulence(turbulence_10ms):
    up, u0, u3 = turbulence_10ms
    assert 0.4 < u0.std() / up.std() < 0.8  # the 0th-harmonic filter removes the small eddies
    assert u3.std() < 0.2 * up.std()


def test_spectrum_follows_kaimal(turbulence_10ms):
    """Band-power ratio low/high against S(f) = σ² (L/v̄)/(1 + 1.5 f L/v̄)^(5/3) (Sørensen et al. 2002 form)."""
    up = turbulence_10ms[0]
    f, pxx = welch(up, fs=1.0 / TURBULENCE_SAMPLE_TIME, nperseg=4096, axis=-1)
    pxx = pxx.mean(axis=0)
    v, sigma, length = 10.0, 1.2, 600.0
    kaimal = sigma**2 * (length / v) / (1.0 + 1.5 * f * length / v) ** (5.0 / 3.0)
    low, high = (f >= 0.005) & (f <= 0.02), (f >= 0.1) & (f <= 0.5)
    measured = pxx[low].sum() / pxx[high].sum()
    analytic = kaimal[low].sum() / kaimal[high].sum()
    assert measured == pytest.approx(analytic, rel=0.35)
    # and the level in the energy-containing range
    mid = (f >= 0.005) & (f <= 0.1)
    assert pxx[mid].sum() == pytest.approx(kaimal[mid].sum(), rel=0.3)


# ---- shear and tower shadow ---------------------------------------------------------------------------------------


def _span_average(local, theta: float) -> float:
    """∫₀^R local(r, θ) 2r/R² dr: a blade's equivalent wind (Dolan & Lehn's span average)."""
    return integrate.quad(lambda r: local(r, theta) * 2.0 * r / P.radius**2, 0.0, P.radius, limit=200)[0]


@pytest.mark.parametrize("theta", [0.0, 0.7, math.pi / 2, 2.0, 2.9, math.pi, 3.3, 4.5, 5.9])
def test_blade_factor_matches_span_integral(theta):
    alpha, h, a, x = 0.1, P.hub_height, wind.TOWER_SHADOW_A, wind.TOWER_SHADOW_X
    m = wind.mean_shear(alpha, P.radius, h)
    # the tower term is exact: potential flow u/V = 1 + a²(y² − x²)/(x² + y²)², y = r sin θ, below the hub only
    shadow = _span_average(
        lambda r, th: a**2 * ((r * math.sin(th)) ** 2 - x**2) / (x**2 + (r * math.sin(th)) ** 2) ** 2, theta
    )
    expected = m * shadow if math.cos(theta) < 0.0 else 0.0
    assert float(wind.tower_shadow_term(np.array(theta), alpha, P.radius, h)) == pytest.approx(expected, abs=1e-9)
    # the shear term is the power law's binomial series to (R/H)³, as in Dolan & Lehn: truncation error < 3e-3
    exact = _span_average(lambda r, th: (1.0 + r * math.cos(th) / h) ** alpha, theta)
    assert float(wind.shear_factor(np.array(theta), alpha, P.radius, h)) == pytest.approx(exact, abs=3e-3)


def test_blade_factor_closed_form_points():
    spec = WindSpec()
    alpha, rh = spec.shear_exponent, P.radius / P.hub_height
    m = 1.0 + alpha * (alpha - 1.0) * rh**2 / 8.0
    a2x2 = (wind.TOWER_SHADOW_A / wind.TOWER_SHADOW_X) ** 2
    c1, c2, c3 = 2 * alpha / 3, alpha * (alpha - 1) / 4, alpha * (alpha - 1) * (alpha - 2) / 15
    up = 1 + c1 * rh + c2 * rh**2 + c3 * rh**3
    down = 1 - c1 * rh + c2 * rh**2 - c3 * rh**3 - m * a2x2  # blade straight down, in front of the tower
    f = blade_factor(np.array([0.0, math.pi / 2, math.pi]), spec, P)
    np.testing.assert_allclose(f, [up, 1.0, down], rtol=1e-12)
    assert down < 0.8  # a deficit of about 22 % for a = 2.2 m, x = 4.7 m
    # rotor mean without shadow: m + α(α−1)(α−2)/60 (R/H)³ cos 3ψ
    psi = np.linspace(0.0, 2 * math.pi, 7)
    no_shadow = WindSpec(tower_shadow=False)
    np.testing.assert_allclose(
        rotor_factor(psi, no_shadow, P),
        m + alpha * (alpha - 1) * (alpha - 2) / 60 * rh**3 * np.cos(3 * psi),
        rtol=1e-12,
    )


def test_rotor_factor_has_period_two_pi_over_three_and_dips_at_the_tower():
    spec = WindSpec()
    psi = np.linspace(0.0, 2 * math.pi, 2001)
    fr = rotor_factor(psi, spec, P)
    np.testing.assert_allclose(rotor_factor(psi + 2 * math.pi / 3, spec, P), fr, rtol=1e-12)
    # deepest where a blade points down: ψ = π, π ± 2π/3
    worst = psi[np.argmin(fr)] % (2 * math.pi / 3)
    assert worst == pytest.approx(math.pi % (2 * math.pi / 3), abs=2e-3)
    assert fr.min() < 0.95 * fr.max()


def test_sampled_blades_follow_the_closed_form():
    spec = WindSpec(mean=[(0.0, 8.0), (10.0, 12.0)], turbulence_intensity=0.0)
    field = WindField(spec, P, _rngs(1, 2), DT)
    azimuth = np.array([0.3, 2.5])
    out = _run(field, 700, azimuth)
    k = np.arange(700)
    psi = azimuth + 1.6 * k[:, None] * DT
    mean = np.interp(k * DT, [0.0, 10.0], [8.0, 12.0])[:, None]
    np.testing.assert_allclose(out["mean"], np.broadcast_to(mean, (700, 2)), rtol=1e-14)
    np.testing.assert_allclose(out["hub"], out["mean"], rtol=1e-14)
    expected = mean[:, :, None] * blade_factor(psi[:, :, None] + wind.BLADE_OFFSETS, spec, P)
    np.testing.assert_allclose(out["blades"], expected, rtol=1e-5)  # azimuth table, linear interpolation
    np.testing.assert_allclose(out["rotor"], out["blades"].mean(axis=-1), rtol=1e-14)


def test_no_turbulence_shear_or_shadow_gives_the_mean_everywhere():
    spec = WindSpec(mean=[(0.0, 6.0), (15.0, 14.0)], turbulence_intensity=0.0, shear_exponent=0.0, tower_shadow=False)
    out = _run(WindField(spec, P, _rngs(5, 6, 7), DT), 2100, np.array([0.0, 1.0, 2.0]))
    np.testing.assert_array_equal(out["hub"], out["mean"])
    np.testing.assert_array_equal(out["blades"], np.broadcast_to(out["mean"][..., None], out["blades"].shape))
    np.testing.assert_allclose(out["rotor"], out["mean"], rtol=1e-15)


# ---- determinism and batching --------------------------------------------------------------------------------------


def test_same_seeds_give_identical_wind():
    spec = WindSpec(mean=[(0.0, 9.0), (30.0, 13.0)])
    azimuth = np.array([0.0, 1.0])
    a = _run(WindField(spec, P, _rngs(11, 12), DT), 2300, azimuth)
    b = _run(WindField(spec, P, _rngs(11, 12), DT), 2300, azimuth)
    for name in a:
        np.testing.assert_array_equal(a[name], b[name])


def test_a_turbine_does_not_depend_on_the_rest_of_its_batch():
    spec = WindSpec(mean=[(0.0, 7.0), (40.0, 15.0)])
    azimuth = np.array([0.4, 2.0, 5.1])
    batch = _run(WindField(spec, P, _rngs(21, 22, 23), DT), 2300, azimuth)  # crosses a chunk boundary at 2000
    alone = _run(WindField(spec, P, _rngs(22), DT), 2300, azimuth[1:2])
    for name in batch:
        np.testing.assert_array_equal(batch[name][:, 1:2], alone[name])
    # the turbulence is continuous across the chunk boundary (linear interpolation from the kept sample)
    step = np.abs(np.diff(batch["hub"], axis=0))
    assert step[1995:2005].max() < 5.0 * np.median(step) + 1e-3


def test_sample_asserts_consecutive_ticks():
    field = WindField(WindSpec(), P, _rngs(1), DT)
    field.sample(0, np.zeros(1))
    with pytest.raises(ValueError, match="tick 1"):
        field.sample(2, np.zeros(1))
