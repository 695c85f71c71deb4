"""The drive-train test's statistics: the 3P lock-in's image at 2·3P in closed form, the whitened amplitude's exact
Rayleigh tail on white noise (where the plain amplitude's is heavier), a 3P tone seen steadily, the learnt scale
unbiased although the samples near the threshold are withheld, and the detector on a healthy drive train through a
torque step against the same drive train with the design fault."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from service.farm.analytic import AnalyticDetector
from service.farm.baseline import LearntRayleighScale, truncated_exponential_mean
from service.farm.interfaces import BETA, OMEGA_G, OMEGA_R, P_G, TAU_G, FarmContext, FarmSample
from service.farm.signals import LockIn3P, lockin_iq_std, rayleigh_threshold
from service.farm.supervisor import FarmSupervisor
from service.plugins import AlgorithmOptionError
from wwcore.channels import N_SENSORS
from wwcore.scenario.farm import FARM_DT_S, FarmPlant
from wwcore.turbine_params import BENCHMARK as P

TAU = 1.5  # s, the detector's lock-in


def _kappa(omega_r: float, tau: float = TAU, dt: float = FARM_DT_S) -> float:
    """|W|/V in steady rotation: (1 − a²)/|1 − a² e^{2j·3ω_rΔt}|."""
    a2 = math.exp(-2.0 * dt / tau)
    return (1.0 - a2) / abs(1.0 - a2 * np.exp(2j * 3.0 * omega_r * dt))


@pytest.mark.parametrize("omega_r", [0.853, 1.2, 1.705])
def test_the_lockin_tracks_its_image_at_twice_3p_in_closed_form(omega_r):
    lockin = LockIn3P(1, TAU)
    for _ in range(400):
        lockin.step(np.zeros(1), np.full(1, omega_r))
    a = math.exp(-FARM_DT_S / TAU)
    assert lockin.v == pytest.approx((1.0 - a) / (1.0 + a), rel=1e-9)  # = 2 s²/σ² (lockin_iq_std)
    assert math.sqrt(lockin.v / 2.0) == pytest.approx(float(lockin_iq_std(1.0, TAU)), rel=1e-9)
    assert abs(lockin.w[0]) / lockin.v == pytest.approx(_kappa(omega_r), rel=1e-9)
    assert 0.13 < _kappa(omega_r) < 0.26  # rated speed … half speed


def test_the_whitened_amplitude_of_white_noise_has_the_rayleigh_tail_and_the_plain_one_a_heavier_one():
    """At half rated speed (ω_r = 0.85 rad/s, κ = 0.26) the plain amplitude exceeds the Rayleigh threshold of
    p = 10⁻³ about 1.5 times as often as p (Hoyt; 6.5 times at the 3 × 3's p = 1.1·10⁻⁷); the whitened one as often
    as p, to the sampling error (≈ 5 %: exceedances come in clumps) and the high-pass's few per cent."""
    rng = np.random.default_rng(21)
    n, samples, settle = 2000, 3300, 300
    lockin = LockIn3P(n, TAU)
    s = float(lockin_iq_std(1.0, TAU))
    p = 1e-3
    h = rayleigh_threshold(s, p)
    plain = whitened = 0
    for k in range(samples):
        lockin.step(rng.standard_normal(n), np.full(n, 0.853))
        if k >= settle:
            plain += int((lockin.amplitude > h).sum())
            whitened += int((lockin.whitened > h).sum())
    count = n * (samples - settle)
    assert plain / count > 1.25 * p
    assert 0.7 * p < whitened / count < 1.15 * p


def test_a_3p_tone_gives_a_steady_whitened_amplitude():
    """x = a cos(φ + ψ) at the lock-in's own phase, half rated speed: A swings around a at 2·3P by its image
    (0.85–1.14 a), Ã within a few per cent of a (the tone's image is weighted a^m, the noise's a^{2m})."""
    n, omega_r, amplitude = 32, 0.853, 1.0
    lockin = LockIn3P(n, TAU)
    psi = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    plain, whitened = [], []
    for k in range(600):
        phase = np.mod(lockin.phase + 3.0 * omega_r * FARM_DT_S, 2.0 * math.pi)  # the phase this step will use
        lockin.step(amplitude * np.cos(phase + psi), np.full(n, omega_r))
        if k >= 300:
            plain.append(lockin.amplitude.copy())
            whitened.append(lockin.whitened.copy())
    plain, whitened = np.array(plain), np.array(whitened)
    assert plain.max() - plain.min() > 0.25
    assert whitened.max() - whitened.min() < 0.25 * (plain.max() - plain.min())
    np.testing.assert_allclose(whitened, amplitude, atol=0.05)
    assert whitened.mean() == pytest.approx(plain.mean(), abs=0.01)


def test_the_truncated_exponential_mean_has_its_closed_form():
    for c in (0.5, 4.0, 4.55, 20.0):
        kept, _ = integrate.quad(lambda u: u * math.exp(-u), 0.0, c)
        assert truncated_exponential_mean(c) == pytest.approx(kept / -math.expm1(-c), rel=1e-9)
    assert truncated_exponential_mean(4.0) == pytest.approx(0.9254, abs=1e-4)


@pytest.mark.parametrize("correct", [True, False])
def test_the_scale_learnt_from_samples_below_half_the_threshold_is_unbiased_only_when_corrected(correct):
    """Noise 1.5 × the design σ, samples withheld where Ã ≥ ½ h(s_learnt) as the detector does (p of the 3 × 3):
    corrected, s is learnt within 1.5 %; uncorrected, 4–6 % low (s² × 0.925, and the lower s withholds more)."""
    rng = np.random.default_rng(22)
    n, design = 400, float(lockin_iq_std(1.0, TAU))
    p3 = 0.01 / (1e4 * 9)
    withheld = 0.25 * math.log(1.0 / p3)
    lockin = LockIn3P(n, TAU)
    scale = LearntRayleighScale(n, design, spread_time_s=60.0, max_ratio=9.0, truncation=withheld if correct else None)
    for k in range(4000):
        lockin.step(1.5 * rng.standard_normal(n), np.full(n, 0.9))
        amplitude = lockin.whitened
        scale.update(amplitude, frozen=(k < 100) | (amplitude >= 0.5 * rayleigh_threshold(scale.scale, p3)))
    learnt = scale.scale.mean() / (1.5 * design)
    if correct:
        assert learnt == pytest.approx(1.0, abs=0.015)
    else:
        # at least the one-pass bias √g = 0.962; lower still, as a low s lowers the withholding level with it
        assert learnt < math.sqrt(truncated_exponential_mean(withheld)) + 0.005


def _samples(detector: AnalyticDetector, z3: np.ndarray, omega_g: np.ndarray, rng: np.random.Generator):
    """Feed the detector 10 Hz samples of one farm whose turbines' torsion-rate residual is ``z3`` (samples, 9):
    generator speed ω_g, rotor speed (ω_g − z3)/N_g, with the design noise of both sensors on each reading's mean;
    power and pitch consistent and quiet. Returns the drive-train flags (samples, 9)."""
    sigma_g, sigma_r = 0.05 / math.sqrt(20.0), 0.008 * math.pi / math.sqrt(20.0)  # means of 10 readings, 2 sensors
    flags = []
    for j in range(len(z3)):
        scada = np.zeros((9, N_SENSORS))
        w_g = omega_g[j] + sigma_g * rng.standard_normal(9)
        w_r = (omega_g[j] - z3[j]) / P.N_g + sigma_r * rng.standard_normal(9)
        scada[:, OMEGA_G] = w_g[:, None]
        scada[:, OMEGA_R] = w_r[:, None]
        scada[:, TAU_G] = 2.0e4
        scada[:, P_G] = P.eta_gc * w_g * 2.0e4
        scada[:, BETA] = 0.0
        sample = FarmSample(
            j + 1, (j + 1) * FARM_DT_S, scada, np.ones(9, np.int8), np.full(9, 2e6), np.array([9.0]), np.array([1e7])
        )
        flags.append(detector.step(sample).faulty[:, 2].copy())
    return np.array(flags)


def test_a_torque_step_on_a_healthy_drive_train_raises_no_flag_and_the_design_fault_does_within_3_s():
    """Half rated speed (ω_g = 81 rad/s, the derated floor). Every 20 s the converter's torque steps by ±1 MN m on
    the low-speed shaft (a derated turbine's pitch and torque jump): the shaft twists by ΔT/K_dt and rings at the
    4.5 Hz mode (ζ = 1 %), so z_3 = N_g dθ/dt carries a pulse of area N_g ΔT/K_dt = 0.035 rad. The drive-train test
    stays quiet. The same drive train with the design fault from 120 s (a 3P swing of N_g 3ω_r e_0 = 1.2 rad/s
    behind the fault's two 0.25 s lags) is flagged within 3 s, on that turbine alone."""
    rng = np.random.default_rng(23)
    samples, onset = 1800, 1200
    t = np.arange(1, samples + 1) * FARM_DT_S
    omega_g = np.full(samples, 81.0)
    omega_r = omega_g / P.N_g
    wn, zeta = 2.0 * math.pi * 4.5, 0.01
    z3 = np.zeros((samples, 9))
    for start in np.arange(30.0, 180.0, 20.0):  # the twist's step response, differentiated, on every turbine
        tau = t - start
        step = (start // 20.0) % 2 * 2.0 - 1.0  # +1, −1 MN m alternately
        wd = wn * math.sqrt(1.0 - zeta**2)
        rate = np.where(tau >= 0.0, wn**2 / wd * np.exp(-zeta * wn * tau) * np.sin(wd * tau), 0.0)
        z3 += (P.N_g * step * 1e6 / P.K_dt * rate)[:, None]
    healthy = AnalyticDetector(context=FarmContext(FarmPlant().site(), 9))
    assert not _samples(healthy, z3, omega_g, rng).any()

    e0 = 5e-3  # rad, the design fault
    phase = np.cumsum(3.0 * omega_r * FARM_DT_S)
    since = np.maximum(t - onset * FARM_DT_S, 0.0)  # s since the onset; the error grows through two 0.25 s lags
    growth = 1.0 - (1.0 + since / 0.25) * np.exp(-since / 0.25)
    faulty_z3 = z3.copy()
    faulty_z3[:, 4] += P.N_g * 3.0 * omega_r * e0 * growth * np.sin(phase)
    detector = AnalyticDetector(context=FarmContext(FarmPlant().site(), 9))
    flags = _samples(detector, faulty_z3, omega_g, rng)
    assert not flags[:onset].any()
    first = np.argmax(flags[:, 4])
    assert flags[first, 4] and (first + 1 - onset) * FARM_DT_S < 3.0
    assert not np.delete(flags, 4, axis=1).any()


def test_the_whitening_option_is_a_validated_boolean_and_off_gives_the_plain_amplitude():
    site = FarmPlant().site()
    for bad, words in (({"whiten_lockin": 1}, "boolean"), ({"whiten_lockins": True}, "whiten_lockins")):
        with pytest.raises(AlgorithmOptionError, match=words):
            FarmSupervisor(site, 9, detector="analytic", options=bad)
    plain = FarmSupervisor(site, 9, detector="analytic", options={"whiten_lockin": False}).detector
    assert plain.whiten is False and FarmSupervisor(site, 9, detector="analytic").detector.whiten is True
