"""The sliding mode observer: existence conditions, canonical form, Lyapunov matrix, reconstruction."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from service.hydro.canonical import ObserverDesignError, check_existence, invariant_zeros
from service.hydro.noise import noise_response
from service.hydro.smo import SMOSettings, TSSlidingModeObserver, design_observer, required_substeps
from service.hydro.supervisor import HydroSupervisor
from tests.hydro.conftest import offset, run_loop
from wwcore.hydro_params import NOMINAL as P
from wwcore.hydro_params import Envelope


def test_existence_conditions_hold_for_every_vertex():
    d = design_observer(P)
    Cs = d.ts.C / d.y_scale[:, None]
    for A in d.ts.A:
        assert np.all(invariant_zeros(A, d.ts.F, Cs).real < 0)
    assert np.linalg.matrix_rank(Cs @ d.ts.F) == np.linalg.matrix_rank(d.ts.F) == 2 < Cs.shape[0]


def test_condition_3_violation_is_a_clear_error():
    # no leakage and an envelope reaching zero stroke on both units: at that vertex neither speed sees Δp,
    # and Δṗ = −k_leak/C_H Δp = 0 is an invariant zero at the origin
    bad = replace(P, k_leak=0.0, envelope=replace(Envelope(), x_p_min=0.0, x_M_min=0.0))
    with pytest.raises(ObserverDesignError, match=r"Condition 3 violated at vertex \d"):
        design_observer(bad)


def test_condition_2_violation_is_a_clear_error():
    d = design_observer(P)
    C = d.ts.C[:3]  # measure only ω_r, ω_g, T_g: the displacement offsets do not show in the outputs
    with pytest.raises(ObserverDesignError, match="Condition 2"):
        check_existence(d.ts.A, d.ts.F, C)


def test_canonical_form_and_gains():
    d = design_observer(P)
    Cs = d.ts.C / d.y_scale[:, None]
    for form, A in zip(d.forms, d.ts.A, strict=True):
        TF = form.T @ d.ts.F
        assert np.abs(TF[:1]).max() < 1e-12  # faults act only on the outputs (22)
        assert np.allclose(Cs @ form.T_inv, np.hstack([np.zeros((5, 1)), np.eye(5)]))  # (28)
        assert form.A11[0, 0] == pytest.approx(-2.0)  # designed pressure-error pole
        assert np.allclose(form.T @ A @ form.T_inv, np.block([[form.A11, form.A12], [form.A21, form.A22]]))
    a22s = -20.0 * np.eye(5)
    assert np.allclose(d.P2 @ a22s + a22s.T @ d.P2, -np.eye(5))  # (26)
    assert required_substeps(SMOSettings(), d.P2, P.dt) == d.substeps == 13


def _observer_run(make_plant, faults, seconds=20.0):
    plant = make_plant(faults, n=2, noise_pct=0.0)
    sup = HydroSupervisor(n=2, params=plant.nominal, compensation=False)
    return run_loop(plant, sup, seconds)


def test_no_fault_reconstructs_zero(make_plant):
    out = _observer_run(make_plant, [], 10.0)
    assert np.abs(out["f_filt"][100:]).max() < 1e-3


def test_constant_offset_is_reconstructed(make_plant):
    out = _observer_run(make_plant, [offset("u_p", -0.2, 2.0, None), offset("u_M", 0.15, 4.0, None)], 10.0)
    s = SMOSettings()
    gain = s.rho * 0.025 / s.delta  # ρ λ_max(P_2)/δ
    expected = np.array([-0.2, 0.15]) * gain / (gain + abs(s.a22s))  # boundary-layer value of (33)
    tail = out["f_filt"][600:]
    assert np.abs(tail - expected).max() < 2e-4
    assert np.abs(tail - np.array([-0.2, 0.15])).max() < 0.02 * 0.2  # within 2 % of the true offsets
    # converged within 1 s of each start
    assert np.abs(out["f_filt"][300:400, :, 0] + 0.2).max() < 0.05 * 0.2
    assert np.abs(out["f_filt"][500:600, :, 1] - 0.15).max() < 0.05 * 0.15


def _offset_run(make_plant, options, seconds=6.0):
    """u_p −0.2 from 2 s, no noise, no compensation: f̂_filt (ticks, runs, 2)."""
    plant = make_plant([offset("u_p", -0.2, 2.0, None)], n=1, noise_pct=0.0)
    sup = HydroSupervisor(n=1, params=plant.nominal, compensation=False, options=options)
    return run_loop(plant, sup, seconds)["f_filt"][:, 0, 0]


def test_the_layer_corrected_injection_removes_the_boundary_layer_bias(make_plant):
    """(35') F_2⁺(v + A22s e_y) is the offset itself in steady state; (35) is it times K/(K + |a22s|)."""
    paper = _offset_run(make_plant, {"tau_filter": [0.05, 0.05]})[400:]
    corrected = _offset_run(make_plant, {"tau_filter": [0.05, 0.05], "layer_correction": True})[400:]
    s = SMOSettings()
    gain = s.rho * 0.025 / s.delta
    assert np.abs(paper - (-0.2) * gain / (gain + abs(s.a22s))).max() < 2e-4  # 0.984 f: the bias of (35)
    assert np.abs(corrected + 0.2).max() < 2e-4 < 0.2 * abs(s.a22s) / (gain + abs(s.a22s))  # below a tenth of it


@pytest.mark.parametrize("tau", [0.025, 0.05])
def test_the_filters_follow_their_closed_form_step_responses(make_plant, tau):
    """(37): 1 − e^(−t/τ); (37'): 1 − (1 + t/τ) e^(−t/τ) (the observer's own 0.8-ms transient aside), and the
    tracking deficit ∫(f − f̂_filt) dt is τ f for (37), 2τ f for (37'): (37') at τ/2 leaves (37)'s at τ."""
    runs = {}
    for order in (1, 2):
        options = {"tau_filter": [tau, tau], "filter_order": order, "layer_correction": True}
        runs[order] = _offset_run(make_plant, options, 4.0)
    t = np.arange(100) * 0.01  # f̂_filt at the sample of 2 s + k dt
    step = {1: 1.0 - np.exp(-t / tau), 2: 1.0 - (1.0 + t / tau) * np.exp(-t / tau)}
    for order in (1, 2):
        measured = runs[order][200:300] / -0.2
        assert np.abs(measured - step[order]).max() < 0.05
        assert _deficit(runs[order]) == pytest.approx(order * tau, rel=0.05)


def _deficit(f_filt: np.ndarray) -> float:
    """∫(f − f̂_filt) dt / f over 2 s from the step at 2 s (trapezoidal rule on the samples)."""
    return float(np.trapezoid(1.0 - f_filt[200:400] / -0.2, dx=0.01))


def test_the_second_order_filter_rolls_off_the_stroke_noise():
    """Two stages at τ/2 (the same step deficit as one at τ) pass less of the differentiated stroke noise."""
    first = noise_response("ts-smo", {"tau_filter": [0.05, 0.05]}, P)
    second = noise_response("ts-smo", {"tau_filter": [0.025, 0.025], "filter_order": 2}, P)
    assert np.all(second.l2 < 0.65 * first.l2)  # 1.08 against 1.76
    # continuous-time estimate for white noise of one sample's variance: ‖h‖₂² ≈ dt τ_p²/(4τ³) + ‖·‖ of the
    # direct term; the derivative part dominates at τ = 0.025 s
    tau, tau_p, dt = 0.025, P.tau_p, P.dt
    assert second.l2[0] == pytest.approx(np.sqrt(dt * tau_p**2 / (4 * tau**3)), rel=0.25)


def test_observer_step_shapes_and_initialisation():
    obs = TSSlidingModeObserver(P, 3)
    y = np.tile([1.0, 122.5, 15000.0, 1.0, 0.75], (3, 1))
    u = np.tile([1.0, 0.75, 15000.0], (3, 1))
    rec = obs.step(y, u)
    assert rec.f_hat.shape == rec.f_filt.shape == (3, 2) and rec.x_hat.shape == (3, 6)
    assert rec.x_hat[0, 2] == pytest.approx(15000.0 / (P.V_M * 0.75), rel=1e-2)  # Δp̂ from the torque balance
