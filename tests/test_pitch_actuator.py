"""The pitch-actuator GLR (``service.turbine.pitch_actuator``): its signatures against an independent filter, its
false-alarm bound in closed form, and on the simulated plant: actuators within tolerance unflagged, actuators that
lost bandwidth flagged on their blade and kept while the fault lasts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter
from scipy.stats import norm

from service.plugins import AlgorithmOptionError
from service.turbine import fast
from service.turbine.component_fdi import ComponentFDI, actuator_whitener
from service.turbine.component_settings import ComponentSettings
from service.turbine.pitch_actuator import FAULTS, TOLERANCE, SignatureBank, glr, glr_threshold
from tests.test_component_fdi import flags_over_time
from wwcore.channels import DIAGNOSIS_TARGETS
from wwcore.scenario import FaultSpec, WindSpec
from wwcore.scenario.mismatch import Mismatch, MismatchSpread
from wwcore.turbine_params import BENCHMARK as P

SIGMA_W2 = 0.75 * 0.2**2  # σ_w² = ¾ σ_β², deg²
ACTUATOR_COLUMNS = [DIAGNOSIS_TARGETS.index(f"pitch_actuator_{i}") for i in (1, 2, 3)]


def _reference(rng, ticks: int, rows: int, time_constant_s: float = 0.5) -> np.ndarray:
    """A moving pitch reference (deg): white noise low-passed with ``time_constant_s``, about 8 deg, 2 deg rms."""
    pole = np.exp(-P.dt / time_constant_s)
    x = lfilter([1.0 - pole], [1.0, -pole], rng.standard_normal((ticks, rows)), axis=0)
    return 8.0 + 2.0 * x / x.std()


def _actuator_filter(omega_n: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """ZOH G_θ as a transfer function in z⁻¹ on the frame's reference (issued at k−1: one tick earlier than the
    ZOH's input), by scipy's discretisation: an implementation independent of ``SignatureBank``'s state space."""
    num, den, _ = cont2discrete(([omega_n**2], [1.0, 2.0 * zeta * omega_n, omega_n**2]), P.dt, method="zoh")
    num = np.ravel(num)[-2:]  # [n1, n2] of n1 z⁻¹ + n2 z⁻², advanced one tick
    return num, den


def _signature(reference: np.ndarray, omega_n: float, zeta: float) -> np.ndarray:
    b, a = actuator_whitener(P)
    theta = lfilter(*_actuator_filter(omega_n, zeta), reference - reference[0], axis=0)
    design = lfilter(*_actuator_filter(P.pitch.omega_n, P.pitch.zeta), reference - reference[0], axis=0)
    return lfilter(b, a, theta - design, axis=0)


def _bank_signatures(reference: np.ndarray) -> np.ndarray:
    bank = SignatureBank(P, *actuator_whitener(P), reference.shape[1])
    return np.concatenate([bank.block(reference[k : k + 10]) for k in range(0, len(reference), 10)])


def test_the_signatures_equal_an_independent_filter_of_the_reference():
    rng = np.random.default_rng(1)
    reference = _reference(rng, 3000, 2)
    s = _bank_signatures(reference)
    candidates = np.concatenate([FAULTS, TOLERANCE])
    for j in (0, 7, len(FAULTS) - 1, len(FAULTS) + 4):
        expected = _signature(reference, *candidates[j])
        assert np.max(np.abs(s[:, :, j] - expected)) <= 1e-9 * np.max(np.abs(expected))
    assert np.max(np.abs(s[:, :, -1])) < 1e-12, "the design actuator (11.11, 0.6) has no signature"


def _window_glr(w: np.ndarray, s: np.ndarray, window: int, n_faults: int, centred: bool = True) -> np.ndarray:
    """Λ (windows, rows, 3) over consecutive, non-overlapping windows; w (ticks, rows, 3), s (ticks, rows, K);
    ``centred``: the window's offset of w maximised out (eq. 5), as ``ComponentFDI`` does."""
    ticks, rows = w.shape[:2]
    m = ticks // window
    ws, ss = w[: m * window].reshape(m, window, rows, 3), s[: m * window].reshape(m, window, rows, -1)
    correlation = np.einsum("mknb,mknc->mnbc", ws, ss)
    energy = np.einsum("mknc,mknc->mnc", ss, ss)
    sum_w, sum_s = ws.sum(axis=1), ss.sum(axis=1)
    variance = np.full((rows, 3), SIGMA_W2)
    return np.array(
        [
            glr(correlation[i], energy[i], variance, n_faults, (sum_w[i], sum_s[i], window) if centred else None)
            for i in range(m)
        ]
    )


def test_a_calibration_bias_is_no_evidence_once_the_offset_is_maximised_out():
    """w = b + white noise, b = 0.1 deg (a quarter of the cross-blade bias tolerance), the pitch ramping 0.4 deg/s
    up and down: on a ramp a slower actuator's signature is a constant lag, −Δτ × rate / 2, which a bias mimics;
    without the nuisance offset the test takes the bias for a slow actuator."""
    rng = np.random.default_rng(5)
    window, rows = 500, 6
    t = np.arange(60 * window)[:, None] * P.dt + rng.uniform(0.0, 20.0, rows)
    reference = 8.0 + 4.0 * np.abs((t / 10.0) % 2.0 - 1.0)  # a triangle: 4 deg in 10 s, then back
    s = _bank_signatures(reference)
    w = 0.1 + np.sqrt(SIGMA_W2) * rng.standard_normal((*reference.shape, 3))
    h = glr_threshold(1e-6, 3 * len(FAULTS))
    biased = _window_glr(w, s, window, len(FAULTS), centred=False).max(axis=2)
    assert (biased > h).mean() > 0.05, np.percentile(biased, [50, 90, 99])
    assert (_window_glr(w, s, window, len(FAULTS)).max(axis=2) > h).mean() == 0.0


def test_one_candidate_against_the_truth_is_normal_with_the_closed_form_mean_and_variance():
    """L(θ) − L(θ_0) ~ N(−d²/2, d²), d² = Σ(s_θ − s_θ0)²/σ_w², with the actuator at θ_0 (eq. 4's step)."""
    rng = np.random.default_rng(2)
    window, rows = 500, 4
    reference = _reference(rng, 400 * window, rows)
    s0, s1 = _signature(reference, 9.0, 0.7), _signature(reference, 5.0, 0.6)
    w = s0[:, :, None] + np.sqrt(SIGMA_W2) * rng.standard_normal((*reference.shape, 3))
    lam = _window_glr(w, np.stack([s1, s0], axis=2), window, 1, centred=False)  # F = {θ}, T = {θ_0}
    d2 = ((s1 - s0) ** 2).reshape(-1, window, rows).sum(axis=1) / SIGMA_W2  # (windows, rows)
    z = (lam + 0.5 * d2[:, :, None]) / np.sqrt(d2[:, :, None])  # standard normal if the closed form holds
    assert abs(z.mean()) < 0.05 and abs(z.std() - 1.0) < 0.05, (z.mean(), z.std())


@pytest.mark.parametrize("truth", [(11.11, 0.6), (8.3, 0.45), (13.9, 0.8)])
def test_the_false_alarm_rate_is_under_its_closed_form_bound(truth):
    """P(max_i Λ_i > h) ≤ 3|F| Q(√(2h)) for an actuator in the tolerance: at a budget of 2 % per window (large
    enough to count), over 1 200 windows of white noise plus the actuator's own signature."""
    rng = np.random.default_rng(3)
    window, rows = 500, 12
    reference = _reference(rng, 100 * window, rows)
    s = _bank_signatures(reference)
    w = _signature(reference, *truth)[:, :, None] + np.sqrt(SIGMA_W2) * rng.standard_normal((*reference.shape, 3))
    w[:, :, 1:] = np.sqrt(SIGMA_W2) * rng.standard_normal((*reference.shape, 2))  # the others: the design
    budget = 0.02
    h = glr_threshold(budget, 3 * len(FAULTS))
    assert 3 * len(FAULTS) * norm.sf(np.sqrt(2.0 * h)) == pytest.approx(budget)
    lam = _window_glr(w, s, window, len(FAULTS))
    assert (lam.max(axis=2) > h).mean() <= budget
    # and a fault's signature, 5.73/0.45 (off the grid), is found in every such window
    w[:, :, 0] += _signature(reference, 5.73, 0.45)
    assert (_window_glr(w, s, window, len(FAULTS))[:, :, 0] > glr_threshold(1e-6, 3 * len(FAULTS))).all()


def _ending_glr(w: np.ndarray, s: np.ndarray, window: int, end: int, n_faults: int) -> np.ndarray:
    """Λ (rows, 3) over the ``window`` ticks before tick ``end``, centred (eq. 5)."""
    ws, ss = w[end - window : end], s[end - window : end]
    correlation, energy = np.einsum("knb,knc->nbc", ws, ss), np.einsum("knc,knc->nc", ss, ss)
    variance = np.full((w.shape[1], 3), SIGMA_W2)
    return glr(correlation, energy, variance, n_faults, (ws.sum(axis=0), ss.sum(axis=0), window))


@pytest.mark.parametrize("fault", [(7.5, 0.6), (2.0, 1.2)])
def test_the_false_clear_rate_over_the_clearing_windows_is_under_its_closed_form_bound(fault):
    """A fault on F's grid that persists: P(max_T L − max_F L ≥ h_c on any of the K clearing windows ending at a
    decision) ≤ K |T| Q(√(2h_c)), the bound (4) with the roles swapped and a union over the windows. At a budget of
    5 % per decision (large enough to count), decisions every 5 s, windows of 1, 2 and 5 s (the shipped ones)."""
    rng = np.random.default_rng(4)
    windows, rows = (100, 200, 500), 12
    reference = _reference(rng, 100 * 500, rows)
    s = _bank_signatures(reference)
    w = _signature(reference, *fault)[:, :, None] + np.sqrt(SIGMA_W2) * rng.standard_normal((*reference.shape, 3))
    budget = 0.05
    h_c = glr_threshold(budget, len(TOLERANCE) * len(windows))
    assert len(TOLERANCE) * len(windows) * norm.sf(np.sqrt(2.0 * h_c)) == pytest.approx(budget)
    decisions = range(500, len(reference) + 1, 500)
    cleared = np.array(
        [np.any([_ending_glr(w, s, m, end, len(FAULTS))[:, 0] <= -h_c for m in windows], axis=0) for end in decisions]
    )
    assert cleared.mean() <= budget, cleared.mean()
    # a healthy actuator after the fault: the short windows give the clearing evidence the full one gives
    healthy = np.sqrt(SIGMA_W2) * rng.standard_normal((*reference.shape, 3))
    short = np.array([_ending_glr(healthy, s, 100, end, len(FAULTS))[:, 0] for end in decisions])
    assert (short <= -h_c).mean() > 0.2


@pytest.mark.parametrize("windows", [(155,), (500,), (100, 100), (600,)])
def test_clearing_windows_that_are_not_whole_blocks_below_the_raise_window_are_refused(windows):
    settings = ComponentSettings(actuator_clear_windows=windows)
    with pytest.raises(AlgorithmOptionError, match="component_actuator_clear_windows"):
        ComponentFDI(P, 1, {"beta_1_m1": 0.2, "tau_g_m": 90.0}, settings)


def test_the_clearing_threshold_splits_the_false_clear_budget_over_its_windows():
    sigma = {"beta_1_m1": 0.2, "tau_g_m": 90.0}
    alpha_c = 0.01 * P.dt * 10 / 1000.0  # the default budget per 0.1-s decision
    one = ComponentFDI(P, 1, sigma, ComponentSettings(actuator_clear_windows=()))
    three = ComponentFDI(P, 1, sigma, ComponentSettings())
    assert one.h_actuator_clear == pytest.approx(0.5 * norm.isf(alpha_c / len(TOLERANCE)) ** 2)
    assert three.h_actuator_clear == pytest.approx(0.5 * norm.isf(alpha_c / (3 * len(TOLERANCE))) ** 2)


def test_the_numba_whitener_equals_the_numpy_reference_bit_for_bit():
    rng = np.random.default_rng(4)
    b, a = actuator_whitener(P)
    e = rng.standard_normal((10, 5, 3))
    s1, s2 = rng.standard_normal((5, 3)), rng.standard_normal((5, 3))
    w_fast = np.empty_like(e)
    z2_fast = fast.whiten_block(e, b[0], b[1], b[2], a[1], a[2], s1.copy(), s2.copy(), w_fast)
    w = np.empty_like(e)
    r1, r2 = s1.copy(), s2.copy()
    for k in range(len(e)):  # ``ComponentFDI._actuators``'s numpy recursion
        wk = np.add(b[0] * e[k], r1, out=w[k])
        r1, r2 = b[1] * e[k] - a[1] * wk + r2, b[2] * e[k] - a[2] * wk
    assert np.array_equal(w_fast, w)
    assert np.array_equal(z2_fast, np.add.accumulate(w * w, axis=0)[-1])


def _actuator_flags(faults, seconds, mismatch=None, seed=5, runs=2, wind=16.0) -> np.ndarray:
    flags = flags_over_time(faults, seconds, WindSpec(mean=[(0.0, wind)]), seed, runs, mismatch)
    return flags[:, :, ACTUATOR_COLUMNS]  # (ticks, rows, 3)


def test_actuators_anywhere_in_their_tolerance_are_not_flagged():
    """Each blade's ω_n drawn in 8.4–13.8 rad/s and ζ in 0.47–0.78 (the whole tolerance, blades unlike)."""
    mismatch = Mismatch(
        pitch_omega_n_rads=11.1,
        pitch_zeta=0.625,
        spread=MismatchSpread(pitch_omega_n_rads=2.7, pitch_zeta=0.15),
    )
    assert not _actuator_flags([], 90.0, mismatch=mismatch, runs=3).any()


def test_a_ramped_pressure_drop_is_flagged_only_outside_the_tolerance_and_cleared_back_inside_it():
    """The benchmark's F7 shape, shortened: actuator 3's (ω_n², 2ζω_n) interpolated from the design's to 3.42/0.9
    over 10 s, held, and back over 10 s. The actuator is inside the tolerance (ω_n ≥ 8.3 rad/s) while the fault
    signal is below 0.488 and in F's range (ω_n ≤ 7.5) above 0.601: the flag rises only after the actuator has left
    the tolerance, never drops while it is still in F's range (on the ramp in, the 5-s window, which mixes
    tolerance and fault, favoured T while the last second said F, and dropped the flag), and is down once the
    actuator has been back inside the tolerance long enough for the pitch to show it."""
    fault = FaultSpec(
        target="pitch_actuator_3", kind="pitch_dynamics", omega_n=3.42, zeta=0.9, start_s=10.0, end_s=60.0, ramp_s=10.0
    )
    flags = _actuator_flags([fault], 75.0, runs=3)
    dt = P.dt
    left_tolerance = round((10.0 + 0.488 * 10.0) / dt)
    back_in_f_range = round((60.0 - 0.601 * 10.0) / dt)  # the last tick of F's range on the way back
    assert not flags[:, :, :2].any(), "nothing on the other blades"
    blade = flags[:, :, 2]
    assert not blade[:left_tolerance].any(), "no flag while the actuator is within its tolerance"
    first = blade.argmax(axis=0)
    assert blade.any(axis=0).all() and (first < back_in_f_range).all(), "raised in every run"
    for row, k in enumerate(first):
        assert blade[k:back_in_f_range, row].all(), "kept while the actuator is in F's range"
    assert not blade[-500:].any(), "down 15 s after the actuator is back inside the tolerance"


def test_a_pressure_drop_is_flagged_on_its_blade_and_kept_while_it_lasts():
    fault = FaultSpec(
        target="pitch_actuator_2", kind="pitch_dynamics", omega_n=5.73, zeta=0.45, start_s=10.0, end_s=70.0
    )
    flags = _actuator_flags([fault], 80.0)
    start, end = round(fault.start_s / P.dt), round(fault.end_s / P.dt)
    assert not flags[:start].any() and not flags[:, :, [0, 2]].any(), "nothing else, nothing before"
    blade = flags[start:end, :, 1]
    assert blade.any(axis=0).all(), "detected in every run"
    first = blade.argmax(axis=0)
    for row, k in enumerate(first):
        assert blade[k:, row].all(), "the flag stays up from its first tick to the fault's end"
