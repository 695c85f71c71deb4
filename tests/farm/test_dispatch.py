"""Dispatch eqs. (18)–(26) and the PI farm controller on hand-computed numbers; eqs. (20)–(22) at a trim point."""

from __future__ import annotations

import numpy as np
import pytest

from plant_sim.turbine.trim import trim
from service.farm.dispatch import Dispatch
from service.farm.hold import HOLD_MARGIN, HOLD_MAX_TORQUE_TSR, HOLD_MIN_TSR
from service.farm.interfaces import BETA, OMEGA_G, OMEGA_R, P_G, TAU_G, FarmContext, FarmSample
from service.farm.power_loop import PIFarmController
from wwcore import aero
from wwcore.channels import N_SENSORS
from wwcore.farm_frames import MIN_SPEED_FRACTION
from wwcore.scenario.farm import FarmPlant
from wwcore.turbine_params import BENCHMARK as P

MW = 1e6


def _sample(demand_mw: float, power_mw: np.ndarray | None = None, held: np.ndarray | None = None) -> FarmSample:
    scada = np.zeros((9, N_SENSORS))
    if power_mw is not None:
        scada[:, P_G] = power_mw * MW
    return FarmSample(
        j=1,
        t=0.1,
        scada=scada,
        zone=np.zeros(9, dtype=np.int8),
        power_ref_used=np.zeros(9),
        mast=np.array([10.0]),
        demand=np.array([demand_mw * MW]),
        held=held,
    )


def _dispatch(
    avail_mw: list[float], rule: str = "paper", trim: tuple[float, float] = (0.0, 0.0), pitch_rule: str = "paper"
) -> Dispatch:
    """Eqs. (18)–(26) on stubbed available powers; the farm-power trim off unless ``trim`` = (K_p, K_i) says."""
    options = {"accommodation_rule": rule, "pitch_rule": pitch_rule, "trim_kp": trim[0], "trim_ki": trim[1]}
    d = Dispatch(context=FarmContext(FarmPlant().site(), 9), options=options)
    d.estimate_available = lambda sample: np.asarray(avail_mw, dtype=float) * MW  # eqs. (20)–(22) stubbed
    return d


def _faulty(**turbines_types) -> np.ndarray:
    f = np.zeros((9, 3), dtype=bool)
    for t, col in turbines_types.items():
        f[int(t[1:]) - 1, col] = True
    return f


def test_eq_18_shares_the_demand_by_available_power():
    refs = _dispatch([1, 2, 3, 1, 2, 3, 1, 2, 3]).step(_sample(12.0), _faulty())
    assert refs / MW == pytest.approx(np.array([1, 2, 3] * 3) / 18.0 * 12.0)


def test_no_dispatch_when_demand_exceeds_the_available_power():
    refs = _dispatch([2.0] * 9).step(_sample(20.0), _faulty())
    assert np.all(refs == P.rated_power)


def test_eqs_23_24_debris_lowers_the_share_then_raises_the_reference():
    refs = _dispatch([2.0] * 9).step(_sample(12.0), _faulty(t1=0)) / MW
    # Σ = 8·2 + 0.97·2 = 17.94; t1: 1.94/17.94·12/0.97; others 2/17.94·12 (all equal to 1.337792…)
    assert refs[0] == pytest.approx(1.94 / 17.94 * 12.0 / 0.97)
    assert refs[1:] == pytest.approx(np.full(8, 2.0 / 17.94 * 12.0))
    assert 8 * refs[1] + 0.97 * refs[0] == pytest.approx(12.0)  # the farm still makes its demand


def test_eqs_25_26_derate_a_faulty_turbine_to_p_min_when_the_others_can_cover():
    refs = _dispatch([2.0] * 9).step(_sample(12.0), _faulty(t2=2)) / MW
    # P_over = 18 − 12 = 6 > 2 → P_avail,f = max(pos(2 − 6), 0.05) = 0.05; Σ = 16.05
    assert refs[1] == pytest.approx(0.05 / 16.05 * 12.0)
    assert refs[0] == pytest.approx(2.0 / 16.05 * 12.0)


def test_eq_26_only_takes_the_headroom():
    refs = _dispatch([2.0] * 9).step(_sample(17.0), _faulty(t2=1)) / MW
    # P_over = 1 → P_avail,f = 2 − 1 = 1; Σ = 17 → refs = P_avail exactly
    assert refs[1] == pytest.approx(1.0) and refs[0] == pytest.approx(2.0)


def test_eq_26_with_two_faulty_turbines_shares_the_headroom_in_turbine_order():
    refs = _dispatch([2.0] * 9).step(_sample(14.5), _faulty(t2=2, t5=1)) / MW
    # P_over = 3.5: t2 → max(2 − 3.5, 0.05) = 0.05 (takes 1.95), P_over = 1.55: t5 → 2 − 1.55 = 0.45
    total = 7 * 2.0 + 0.05 + 0.45
    assert refs[1] == pytest.approx(0.05 / total * 14.5)
    assert refs[4] == pytest.approx(0.45 / total * 14.5)
    assert refs.sum() == pytest.approx(14.5)


def test_the_trim_moves_the_free_turbines_by_the_pi_of_the_farm_power_error():
    kp, ki = 0.5, 0.5
    d = _dispatch([2.0] * 9, trim=(kp, ki))
    short = np.full(9, 12.0 / 9)
    short[0] -= 0.3  # the farm makes 11.7 of 12 MW
    e = 0.3 / 12.0
    eq_18 = 12.0 / 16.05  # t2 derated to P_min (26): the others' share
    for k in range(1, 4):
        refs = d.step(_sample(12.0, short), _faulty(t2=2)) / MW
        u = kp * e + k * ki * e * 0.1  # I after k samples of Δt = 0.1 s
        assert refs[0] == pytest.approx(2.0 * eq_18 * (1.0 + u))
        assert refs[1] == pytest.approx(0.05 * eq_18)  # the derated turbine is left alone
    over = np.full(9, 13.0 / 9)  # 1 MW too much: the integral comes down again
    refs = d.step(_sample(12.0, over), _faulty(t2=2)) / MW
    u = kp * (-1.0 / 12.0) + (3 * e - 1.0 / 12.0) * ki * 0.1
    assert refs[0] == pytest.approx(2.0 * eq_18 * (1.0 + u))


def test_the_trim_saturates_and_restarts_when_the_farm_cannot_meet_the_demand():
    d = _dispatch([2.0] * 9, trim=(0.5, 0.5))
    nothing = np.zeros(9)
    for _ in range(50):
        refs = d.step(_sample(12.0, nothing), _faulty()) / MW
    assert refs == pytest.approx(np.full(9, 12.0 / 9 * (1.0 + d.power_trim.limit)))  # u = +10 % at most
    assert d.power_trim.integral[0] == pytest.approx(d.power_trim.limit)
    refs = d.step(_sample(20.0, nothing), _faulty())  # beyond Σ P_avail: rated, and the integral restarts
    assert np.all(refs == P.rated_power) and d.power_trim.integral[0] == 0.0


def test_without_gains_the_trim_leaves_eq_18_alone():
    refs = _dispatch([1, 2, 3, 1, 2, 3, 1, 2, 3]).step(_sample(12.0, np.zeros(9)), _faulty())
    assert refs / MW == pytest.approx(np.array([1, 2, 3] * 3) / 18.0 * 12.0)


def _held(wind: float, tau_g: float) -> tuple[Dispatch, FarmSample]:
    """A hold-torque dispatch whose low-passed wind is set by hand; SCADA torque τ_g."""
    d = _dispatch([2.0] * 9, rule="hold-torque")
    d.available.slow_wind = np.full(9, wind)
    sample = _sample(12.0)
    sample.scada[:, TAU_G] = tau_g
    return d, sample


def _hold_cap(wind: float, omega_g: float) -> float:
    """S_max: the generator-side sum τ_g + B_g ω_g the rotor holds at fine pitch with HOLD_MARGIN in hand."""
    omega_r = omega_g / P.N_g
    cq = aero.torque_coefficient(np.array([omega_r * P.radius / wind]), np.zeros(1))[0]
    return P.eta_dt * (P.aero_torque_gain * cq * wind**2 / HOLD_MARGIN - P.B_r * omega_r) / P.N_g


def _tsr(omega_g: float, wind: float) -> float:
    return omega_g / P.N_g * P.radius / wind


@pytest.mark.parametrize(
    "tau_g, kept",
    [(15e3, True), (26e3, True), (32e3, False)],  # kept at λ_f; kept at a faster speed; more than any λ gives
)
def test_hold_torque_keeps_the_torque_at_the_slowest_speed_that_holds_it(tau_g, kept):
    wind = 12.0
    d, sample = _held(wind, tau_g)
    refs = d.step(sample, _faulty(t2=2)) / MW
    omega_floor = d.drivetrain.speed_floor[1]
    tsr = _tsr(omega_floor, wind)
    cap = _hold_cap(wind, omega_floor)
    assert d.held_torque[1] == pytest.approx(cap)
    assert HOLD_MIN_TSR <= tsr <= HOLD_MAX_TORQUE_TSR + 1e-9
    slower = omega_floor * (tsr - 0.05) / tsr  # the next slower speed the hold could have chosen
    if tau_g == 15e3:
        assert tsr == pytest.approx(HOLD_MIN_TSR)  # the rotor holds it at λ_f already
    elif kept:
        assert tsr > HOLD_MIN_TSR and cap >= tau_g > _hold_cap(wind, slower)
    else:
        assert tsr == pytest.approx(HOLD_MAX_TORQUE_TSR) and cap < tau_g
        speeds = np.linspace(HOLD_MIN_TSR, 9.0, 81) * P.N_g * wind / P.radius
        assert cap == pytest.approx(max(_hold_cap(wind, w) for w in speeds), rel=2e-3)  # the most it can hold
    held = min(tau_g, cap)  # S of the SCADA torque (ω̄_g = 0 in this sample), capped only if no λ keeps it
    assert (held == tau_g) == kept
    floor = P.eta_gc * (held - P.B_g * omega_floor) * omega_floor / MW  # P_min,f
    # P_over = 6 > 2 − floor: the turbine gets its floor, the other eight share the rest of the demand
    assert refs[1] == pytest.approx(floor)
    assert refs[[0, 2, 3, 4, 5, 6, 7, 8]] == pytest.approx(np.full(8, (12.0 - floor) / 8))
    assert d.mode[1] == 3 and np.all(d.mode[np.arange(9) != 1] == 0)
    assert np.isnan(np.delete(d.held_torque, 1)).all()


def test_hold_torque_speed_floor_stays_at_the_lowest_set_point_in_low_wind():
    d, sample = _held(6.0, 8e3)  # λ_f = 5 would ask for 0.31 Ω_nom
    d.step(sample, _faulty(t2=2))
    assert d.drivetrain.speed_floor[1] == pytest.approx(MIN_SPEED_FRACTION * P.omega_nom)
    assert d.held_torque[1] == pytest.approx(_hold_cap(6.0, d.drivetrain.speed_floor[1]))


def test_a_held_turbine_stays_at_its_floor_when_the_farm_cannot_meet_the_demand():
    """At once, that is: the hold is released only when the farm has needed it for a while (test_accommodation)."""
    d, sample = _held(12.0, 15e3)
    sample.demand[:] = 20.0 * MW  # above Σ P_avail = 18 MW: no dispatch, every other turbine at rated
    refs = d.step(sample, _faulty(t2=2))
    floor = P.eta_gc * (15e3 - P.B_g * d.drivetrain.speed_floor[1]) * d.drivetrain.speed_floor[1]
    assert refs[1] == pytest.approx(floor)
    assert np.all(np.delete(refs, 1) == P.rated_power)


def test_hold_torque_floor_is_fixed_while_the_hold_lasts_and_forgotten_after():
    d, sample = _held(15.0, 26e3)
    d.step(sample, _faulty(t2=2))
    first, cap = d.drivetrain.speed_floor[1], d.held_torque[1]
    d.available.slow_wind = np.full(9, 25.0)  # eq. (20) reads nonsense while the rotor slows
    d.step(sample, _faulty(t2=2))
    assert d.drivetrain.speed_floor[1] == first and d.held_torque[1] == cap
    d.step(sample, _faulty())
    assert np.isnan(d.drivetrain.speed_floor).all() and np.isnan(d.held_torque).all() and np.all(d.mode == 0)


def test_a_held_turbine_keeps_its_floor_when_its_torque_falls_in_a_lull():
    """The floor is the torque sum latched when the hold began. One that followed the measured sum would lower
    the set point as the controller's zone-0 taper lowers the torque in a lull, and the taper's knee with it,
    until the rotor stalled (measured: λ 2.7, 0.7 MN m on the shaft for 200 s at 12 m/s)."""
    d, sample = _held(12.0, 26e3)
    first = d.step(sample, _faulty(t2=2))[1]
    floor = P.eta_gc * (26e3 - P.B_g * d.drivetrain.speed_floor[1]) * d.drivetrain.speed_floor[1]
    assert first == pytest.approx(floor)
    sample.scada[:, TAU_G] = 15e3  # the rotor could not make the held torque: the taper gave it away
    again = d.step(sample, _faulty(t2=2))[1]
    assert again == first
    d.step(sample, _faulty())
    assert np.isnan(d.drivetrain.held_sum).all()  # forgotten with the hold


def test_hold_torque_applies_to_the_drive_train_only():
    d, sample = _held(15.0, 26e3)
    refs = d.step(sample, _faulty(t2=1)) / MW  # pitch misalignment: eq. (26) as published
    assert refs[1] == pytest.approx(0.05 / 16.05 * 12.0) and d.mode[1] == 2


def test_an_unknown_accommodation_rule_is_refused():
    with pytest.raises(ValueError, match="accommodation_rule"):
        Dispatch(context=FarmContext(FarmPlant().site(), 9), options={"accommodation_rule": "magic"})


def test_eqs_20_22_recover_the_wind_and_the_available_power_at_a_steady_point():
    op = trim(P, 14.0, 3.0 * MW)  # derated to 3 MW at 14 m/s: pitched, at Ω_nom
    d = Dispatch(context=FarmContext(FarmPlant().site(), 9))
    d.p_ref = np.full(9, 3.0 * MW)
    scada = np.zeros((9, N_SENSORS))
    scada[:, OMEGA_G] = op.omega_g
    scada[:, OMEGA_R] = op.omega_r
    scada[:, TAU_G] = op.tau_g
    scada[:, BETA] = op.pitch
    scada[:, P_G] = op.power
    sample = FarmSample(
        1, 0.1, scada, np.ones(9, dtype=np.int8), np.full(9, 3 * MW), np.array([14.0]), np.array([20 * MW])
    )
    avail = d.estimate_available(sample)
    assert d.wind == pytest.approx(np.full(9, 14.0), rel=2e-3)  # eq. (20)
    assert avail == pytest.approx(np.full(9, 4.8 * MW), rel=1e-3)  # eq. (22): pos(4.8 − 3) + 3


def test_pi_controller_by_hand():
    pi = PIFarmController(context=FarmContext(FarmPlant().site(), 9))
    refs = pi.step(_sample(12.0, np.full(9, 10.0 / 9.0)), _faulty())
    e = (12.0 - 10.0) / 12.0
    u = 0.3 * e + 0.05 * e * 0.1
    assert refs / MW == pytest.approx(np.full(9, 12.0 / 9.0 * (1.0 + u)))
    for _ in range(2000):  # a persistent error saturates at +20 %
        refs = pi.step(_sample(12.0, np.full(9, 5.0 / 9.0)), _faulty())
    assert refs / MW == pytest.approx(np.full(9, 12.0 / 9.0 * 1.2))
