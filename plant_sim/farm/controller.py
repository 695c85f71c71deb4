r"""The turbine controller of a farm turbine: the benchmark's controller, able to follow a power reference.

The benchmark controller (``plant_sim.turbine.controller``) regulates the generator speed to Ω_nom in region 3
and enters region 3 when P_g ≥ P_r. Below rated wind a reference P_r < P_avail makes it switch zones every tick
(region 3 at ω_g < Ω_nom − Ω_Δ is left at once), the pitch chatters between 0 and −2 deg, the drive train rings
and the turbine produces its available power anyway: measured with this plant at 7–11 m/s and P_r = 0.8 P_avail,
≈ 13 000–28 000 zone switches per 300 s and P_g ≈ P_avail (``docs/farm.md``). A farm dispatch needs turbines that
follow their references, so the farm turbine derates by speed [PROPOSED]: its region-3 speed set point follows
the reference,

.. math::

    ω_{set} = \operatorname{clip}\bigl(Ω_{nom}\,(P_r / P_{rated})^{1/3},\ ω_{min},\ Ω_{nom}\bigr),\qquad
    Ω_{Δ,set} = Ω_Δ\, ω_{set}/Ω_{nom}

(close to the region-2 speed of power P_r: K_opt η_gc Ω_nom³ = 1.06 P_rated), so that the zone logic, the PI pitch
loop and the constant-power torque of the benchmark are used unchanged with Ω_nom → ω_set, Ω_Δ → Ω_Δ,set:

.. code-block:: text

    zone 0 → 1 when P_g ≥ P_r or ω_g ≥ ω_set;   zone 1 → 0 when ω_g < ω_set − Ω_Δ,set
    zone 0: β_ref = 0, τ_g,r = K_opt ω_g²;      zone 1: β_ref = PI(ω_g − ω_set), τ_g,r = P_r/(η_gc ω_g)

**Derating at held torque** [PROPOSED], for a turbine whose reference comes with ``hold_torque`` (the dispatch's
drive-train accommodation, ``service.farm.dispatch``). The sum S = τ_g,r + B_g ω_g (N_g S/η_dt is the shaft torque
in steady state) is latched when the hold begins, capped by ``held_torque`` when the reference carries one (S then
slews down to the cap at the torque equivalent of ``RAMP_FRACTION_PER_S``), and the speed set point carries the
derating:

.. math::

    P_r = η_{gc} (S − B_g ω_{set})\, ω_{set}\ \text{(smaller root, clipped to } [ω_{min}, Ω_{nom}]),\qquad
    τ_{g,r} = S − B_g ω_g\ \text{(zone 1)}

so the power falls with the speed while the shaft torque stays where it was (or moves once, to the cap). Why: the
drive-train fault's 3P torque swing grows with ω_r² (``plant_sim.turbine.plant``), and a rainflow count charges a
derating that moves the mean torque with one cycle as large as the torque change. The set point moves at most
``SPEED_SLEW`` (the generator's inertia torque while it slows stays ≈ 0.15 MN m on the shaft). Zone 1 is entered on
speed only (a held torque above the set point makes more than P_r). A rotor that cannot hold the torque at its set
point (too little wind for that speed) falls into zone 0, where the torque is (S − B_g ω_g)(ω_g/(ω_set −
Ω_Δ,set))⁶ and settles with the torque at what the wind gives; the dispatch chooses the set point and the cap with
torque in hand so that this stays rare. When the flag clears, the set point climbs back at ``SPEED_SLEW`` and S
moves from its held value to the normal law's, P_r/(η_gc ω_n) + B_g ω_n at the normal set point ω_n, in proportion
to the speed the rotor has regained (in zone 0 too, tapered the same way below the set point the hold had); the
hold ends once the speed has reached ω_n, where S already is the normal law's, so the torque does not step.

The power reference a turbine receives is followed at most at ``RAMP_FRACTION_PER_S`` (10 % of rated per
second, a usual curtailment ramp [PROPOSED]), so a sudden accommodation (eq. (26) may ask for 50 kW at once) does
not throw the pitch to feather.

**Drive-train damper** [PROPOSED]. The constant-power torque law has negative damping on the 4.5 Hz torsion mode,
dτ_g/dω_g = −P_r/(η_gc ω_g²), which the benchmark's B_g = 45.6 N m s/rad does not outweigh once the pitch loop is
saturated: in zone 1 with β at its −2 deg stop (the wind just below what the reference needs, which a derated
turbine meets often), the mode grows without bound (measured with this plant at 9 m/s, P_r ≈ 0.9 MW: the shaft
torque oscillation at 4.47 Hz grew from 0.02 to 2.7 MN m std in 100 s; the benchmark turbine alone shows the same
near rated wind). Industrial controllers add a drive-train damper; so does the farm turbine:

.. math::  τ_{g,r} \mathrel{+}= G_d\, \frac{2ζ_d ω_d s}{s^2 + 2ζ_d ω_d s + ω_d^2}\, ω_{g,m},\qquad
           ω_d = 2π\,4.5\ \text{rad/s},\ ζ_d = 0.3,\ G_d = 1000\ \text{N m s/rad}

(bilinear at Ts). G_d adds ≈ 2.7 % critical damping to the mode (J_eq = 367 kg m² on the generator side); at 3P
(0.5–0.8 Hz) its gain is below 12 %.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from plant_sim.turbine.controller import BenchmarkController
from wwcore.farm_frames import MIN_SPEED_FRACTION
from wwcore.turbine_frames import TurbineRefs
from wwcore.turbine_params import TurbineParams

RAMP_FRACTION_PER_S = 0.1  # – of rated power per second, largest change of the followed reference [PROPOSED]
SPEED_SLEW = 0.02  # Ω_nom per second: a held turbine's speed set point moves at most 3.2 rad/s² [PROPOSED]
DAMPER_HZ = 4.5  # Hz, centre of the drive-train damper: the torsion mode (PARAMETERS.md a.1) [PROPOSED]
DAMPER_ZETA = 0.3  # –, damping of the band-pass (its width) [PROPOSED]
DAMPER_GAIN = 1000.0  # N m s/rad on the generator side at the centre frequency [PROPOSED]


def speed_setpoint(params: TurbineParams, power_ref: np.ndarray) -> np.ndarray:
    """ω_set = clip(Ω_nom (P_r/P_rated)^{1/3}, ω_min, Ω_nom) in rad/s for references P_r in W."""
    ratio = np.maximum(power_ref, 0.0) / params.rated_power
    return np.clip(params.omega_nom * np.cbrt(ratio), MIN_SPEED_FRACTION * params.omega_nom, params.omega_nom)


class FarmTurbineController(BenchmarkController):
    """The benchmark controller for n farm turbines, derating by speed set point (module docstring)."""

    def __init__(self, params: TurbineParams, n: int, power_reference: float):
        super().__init__(params, n, power_reference)
        self.power_ref_target = np.full(n, float(power_reference))  # W, the last reference received
        self.ramp = RAMP_FRACTION_PER_S * params.rated_power * params.dt  # W per tick
        self.setpoint = speed_setpoint(params, self.power_ref)
        self._hysteresis = self._hysteresis_at(self.setpoint)
        self._ramping = False
        w0 = 2.0 * math.pi * DAMPER_HZ
        b, a, _ = signal.cont2discrete(
            ([DAMPER_GAIN * 2.0 * DAMPER_ZETA * w0, 0.0], [1.0, 2.0 * DAMPER_ZETA * w0, w0 * w0]), params.dt, "bilinear"
        )
        self._bp_b, self._bp_a = np.ravel(b), np.ravel(a)
        self._bp_state = np.zeros((2, n))  # transposed direct form II
        self._bp_ready = False
        self.damper_torque = np.zeros(n)  # N m, the damper's share of τ_g,r
        self.hold = np.zeros(n, dtype=bool)  # derating at held torque (module docstring)
        self.hold_asked = np.zeros(n, dtype=bool)  # the last reference asked for it
        self.tau_hold = np.zeros(n)  # N m, generator side, the held sum S = τ_g + B_g ω_g
        self._omega_g = np.zeros(n)  # rad/s, the last generator speed the controller used
        self._hold_set = np.zeros(n)  # rad/s, ω_set while in the hold
        self._release_from = np.zeros(n)  # rad/s, the hold's set point when the flag cleared
        self._hold_target = np.zeros(n)  # N m, the held sum S that tau_hold slews down to
        self._release_sum = np.zeros(n)  # N m, the held sum when the flag cleared
        self.torque_slew = RAMP_FRACTION_PER_S * params.rated_power / (params.eta_gc * params.omega_nom) * params.dt

    def initialise(self, zone: np.ndarray, beta_ref: np.ndarray, tau_g_ref: np.ndarray) -> None:
        super().initialise(zone, beta_ref, tau_g_ref)
        self._bp_ready = False  # the damper's state is set from the first speed reading (steady state)

    def set_reference(
        self, power_ref: np.ndarray, hold_torque: np.ndarray | None = None, held_torque: np.ndarray | None = None
    ) -> None:
        """A new power reference per turbine (W) from the farm controller, followed at the ramp rate;
        ``hold_torque`` (n,) bool asks for the derating at held torque, ``held_torque`` (n,) N m caps the torque
        sum it holds (NaN: no cap; module docstring)."""
        self.power_ref_target = np.minimum(np.maximum(np.asarray(power_ref, dtype=float), 0.0), self.p.rated_power)
        self._ramping = True
        asked = np.zeros(self.n, dtype=bool) if hold_torque is None else np.asarray(hold_torque, dtype=bool)
        starting = asked & ~self.hold
        if starting.any():  # S = τ_g + B_g ω_g: the shaft torque in steady state, N_g S/η_dt
            omega_g = np.where(self._omega_g > 0.0, self._omega_g, self.setpoint)  # before the first step: trimmed
            held = self.tau_g_ref - self.damper_torque + self.p.B_g * omega_g
            self.tau_hold = np.where(starting, held, self.tau_hold)
            target = held if held_torque is None else np.fmin(held, held_torque)
            self._hold_target = np.where(starting, target, self._hold_target)
            self._hold_set = np.where(starting, self.setpoint, self._hold_set)
        releasing = self.hold & self.hold_asked & ~asked  # the climb back starts from where the hold stands
        if releasing.any():
            self._release_from = np.where(releasing, self._hold_set, self._release_from)
            self._release_sum = np.where(releasing, self.tau_hold, self._release_sum)
        self.hold_asked = asked
        self.hold = self.hold | starting

    def _hysteresis_at(self, setpoint: np.ndarray) -> np.ndarray:
        """Ω_Δ,set = Ω_Δ ω_set/Ω_nom, rad/s."""
        return self.p.omega_delta * setpoint / self.p.omega_nom

    def _hold_setpoint(self, omega_g: np.ndarray) -> None:
        """ω_set and S of turbines in the hold: ω_set slewed at SPEED_SLEW, S slewed to the dispatch's cap; on
        release both climb back (S in proportion to the speed regained) and the hold ends at the normal law's point."""
        p = self.p
        normal = speed_setpoint(p, self.power_ref)
        releasing = self.hold & ~self.hold_asked
        # P_r = η_gc (S − B_g ω) ω at the held sum S = τ_g + B_g ω_g: the smaller root
        s_hold = np.maximum(self.tau_hold, 1.0)
        disc = np.maximum(s_hold * s_hold - 4.0 * p.B_g * self.power_ref / p.eta_gc, 0.0)
        held = 2.0 * self.power_ref / (p.eta_gc * (s_hold + np.sqrt(disc)))
        slew = SPEED_SLEW * p.omega_nom * p.dt
        held = np.clip(held, MIN_SPEED_FRACTION * p.omega_nom, p.omega_nom)
        target = np.where(releasing, normal, held)
        self._hold_set = np.minimum(np.maximum(target, self._hold_set - slew), self._hold_set + slew)
        tau_hold = np.clip(self._hold_target, self.tau_hold - self.torque_slew, self.tau_hold + self.torque_slew)
        if releasing.any():
            normal_sum = self.power_ref / (p.eta_gc * normal) + p.B_g * normal
            span = np.maximum(normal - self._release_from, 1e-6)
            climbed = np.clip((omega_g - self._release_from) / span, 0.0, 1.0)
            tau_hold = np.where(releasing, self._release_sum + (normal_sum - self._release_sum) * climbed, tau_hold)
        self.tau_hold = tau_hold
        back = releasing & (self._hold_set >= normal) & (omega_g >= normal - self._hysteresis_at(normal))
        self.hold = self.hold & ~back
        self.setpoint = np.where(self.hold, self._hold_set, normal)
        self._hysteresis = self._hysteresis_at(self.setpoint)

    def step(self, k: int, omega_g_m: np.ndarray, p_g_m: np.ndarray, refs: TurbineRefs | None) -> None:
        """τ_g,r and β_ref for tick k from the turbine's own sensors (``refs`` is not used by farm turbines)."""
        p = self.p
        omega_g = omega_g_m
        if self._ramping:  # the reference moves towards the farm's at most ``ramp`` per tick
            step = np.minimum(np.maximum(self.power_ref_target - self.power_ref, -self.ramp), self.ramp)
            self.power_ref = self.power_ref + step
            self._ramping = bool(np.any(self.power_ref != self.power_ref_target))
            self.setpoint = speed_setpoint(p, self.power_ref)
            self._hysteresis = self._hysteresis_at(self.setpoint)
        if self.hold.any():
            self._hold_setpoint(omega_g)
        setpoint, hysteresis = self.setpoint, self._hysteresis
        to_region3 = (omega_g >= setpoint) | ((p_g_m >= self.power_ref) & ~self.hold)
        stay_region3 = omega_g >= setpoint - hysteresis
        region3 = np.where(self.zone == 0, to_region3, stay_region3)
        self.zone = region3.view(np.int8)
        error = omega_g - setpoint
        lo, hi = p.pitch_min_deg, p.pitch_max_deg
        self.integrator = np.minimum(np.maximum(self.integrator + p.dt * error, lo), hi)
        beta_pi = np.minimum(np.maximum(p.K_p * error + p.K_i * self.integrator, lo), hi)
        self.beta_ref = np.where(region3, beta_pi, 0.0)
        safe_omega = np.maximum(omega_g, 1.0)
        self._omega_g = omega_g
        # drive-train damper: band-pass of ω_g,m at the torsion mode (transposed direct form II; b1 = 0)
        b, a, z = self._bp_b, self._bp_a, self._bp_state
        if not self._bp_ready:  # steady state of the band-pass for a constant input: zero output
            z[0] = z[1] = -b[0] * omega_g
            self._bp_ready = True
        damper = b[0] * omega_g + z[0]
        z[0] = z[1] - a[1] * damper
        z[1] = b[2] * omega_g - a[2] * damper
        self.damper_torque = damper
        base = np.where(region3, self.power_ref / (p.eta_gc * safe_omega), p.k_opt * omega_g * omega_g)
        if self.hold.any():
            # zone 0 in the hold: too little wind for the set point (or, on the way back, for the climb): let the
            # torque go steeply below the speed the rotor last held
            held_speed = np.where(self.hold_asked, setpoint, self._release_from)
            below = np.minimum(omega_g / np.maximum(held_speed - hysteresis, 1.0), 1.0)
            cube = below * below * below
            torque = self.tau_hold - p.B_g * omega_g
            base = np.where(self.hold, np.where(region3, torque, torque * cube * cube), base)  # (ω_g/ω_b)⁶
        self.tau_g_ref = base + damper
