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
drive-train accommodation, ``service.farm.hold``). The sum S = τ_g,r + B_g ω_g (N_g S/η_dt is the shaft torque
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
hold ends once the speed has reached ω_n, where S already is the normal law's, so the torque does not step. A
rotor that is below the hold's set point when the flag clears (a lull during the hold left it in zone 0, where the
steep law can hold it stalled: measured 60 rad/s at 12.5 m/s, λ ≈ 3, 0.5 MW) would meet the held torque again on
that climb and stay there; it leaves the hold at once instead, and its torque fades from where it is to the normal
laws' (K_opt ω_g² in zone 0, under which it speeds up to its best tip-speed ratio) over ``RELEASE_FADE_S``.

**3P cancellation** [PROPOSED]. The drive-train fault's transmission error e(ψ) = e_0 cos 3ψ is
kinematic: below the torsion mode the generator follows it, and the shaft carries the torque that accelerates the
generator, J_g N_g² (3ω_r)² e_0/η_dt at 3P (0.46 MN m at rated speed, e_0 = 5 mrad). While a turbine is asked to
cancel it (``cancel_3p``, the dispatch's default for a flagged drive train) or to hold, its converter supplies that
torque instead, so the shaft does not have to:

.. math::

    τ_{g,r} \mathrel{+}= −J_g\,\dot v,\qquad
    v = \mathrm{SOGI}_{ω_3}\bigl(\mathrm{SOGI}_{ω_3}(ω_{g,m})\bigr),\qquad ω_3 = 3\,ω_{g,m}/N_g

Each SOGI (second-order generalised integrator: v̇ = kω_3(u − v) − ω_3 q, q̇ = ω_3 v) is a band-pass of unit gain
and zero phase at ω_3; two in a row pass ω_g,m's 3P swing and give its derivative v̇ from their states, without
differencing noise. Both start wide, k = ``RIPPLE_SOGI_GAIN`` (locked in ≈ 1 s), and narrow linearly to
``RIPPLE_TRACK_GAIN`` over ``RIPPLE_NARROW_S``; their input is ω_g,m less its ``RIPPLE_MEAN_S`` low-pass, so that
the states' steady state does not move with k. Why narrow: −J_g v̇ is a negative damping, J_g ω |H²| sin(−∠H²),
for anything the pair lets through above ω_3, where its phase lags. Above the pair rolls off as 1/s², so the
4.5 Hz torsion mode is safe, but the pitch loop's ≈ 1.1 Hz mode above rated is not: with k = 0.8 (|H²| ≈ 0.6 at
1.4 ω_3) it rang at 3.0–3.4 deg rms (15–18 m/s) and put ≈ 100 kW of 1.1 Hz into the turbine's power; at k = 0.1
|H²| is 0.02 there (``tests/farm/test_accommodation.py``). The control laws (zone logic, pitch PI, torque laws, the
hold) read ω_g,m − v and P_g,m less the cancellation's power; the damper reads ω_g,m. The cancellation fades in and
out over ``RIPPLE_ENGAGE_S``, and the filter runs only while it is engaged. Scenario option ``[plant]
cancel_3p_in_hold = false`` leaves the hold, and ``cancel_3p`` (mode 5), without it. Measured with this plant
(12 m/s, 10 % turbulence, 3 MW, one turbine, k = 0.8 before the narrowing): the shaft's 3P swing falls from 0.27
to 0.006 MN m and its rainflow damage (Σ S⁴ over 70 s) from 3.99 to 0.72 (MN m)⁴, against 0.52 without the fault.
The price is a 3P ripple in the turbine's electrical power,
η_gc ω_g J_g v̇ (≈ 0.3 MW at 12 m/s and 3 MW, 0.75 MW at rated speed): the power the shaft swung back and forth
now goes through the converter. The other turbines of the farm cancel it at the farm's terminals (below). A
reference with ``cancel_3p`` asks for the cancellation without the hold (the dispatch's mode 5).

**Power phasors** [PROPOSED]. A reference may carry a phasor C (W) and a rate ω (rad/s), ``ripple_power`` and
``ripple_rate``: the turbine adds Re{C e^{jω(t − t_c)}} to its electrical power until the next reference, t_c the
time of the farm sample the reference was computed from, as the torque ΔP/(η_gc ω_g,m) held over each tick and
taken at the tick's middle, with the converter's lag α_gc/(s + α_gc) taken out in advance (C (1 + jω/α_gc)). The
farm controller asks the free turbines for the opposite of a cancelling turbine's 3P power ripple this way
(``service.farm.ripple``). The control laws do not see the added power; a phasor ``EXTRA_MAX_AGE_S`` old is
dropped (its supervisor has gone quiet).

**Per-blade pitch trim** [PROPOSED]. A reference may carry ``pitch_trim`` (deg per blade), which is added to each
blade's actuator command until the next reference: the farm supervisor's virtual actuator for a pitch
misalignment (``service.farm.pitch_trim``). The turbine's own loops do not see it; its encoders do.

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
from wwcore.backend import fast_module
from wwcore.farm_frames import MIN_SPEED_FRACTION
from wwcore.turbine_frames import TurbineRefs
from wwcore.turbine_params import TurbineParams

RAMP_FRACTION_PER_S = 0.1  # – of rated power per second, largest change of the followed reference [PROPOSED]
SPEED_SLEW = 0.02  # Ω_nom per second: a held turbine's speed set point moves at most 3.2 rad/s² [PROPOSED]
DAMPER_HZ = 4.5  # Hz, centre of the drive-train damper: the torsion mode (PARAMETERS.md a.1) [PROPOSED]
DAMPER_ZETA = 0.3  # –, damping of the band-pass (its width) [PROPOSED]
DAMPER_GAIN = 1000.0  # N m s/rad on the generator side at the centre frequency [PROPOSED]
RIPPLE_SOGI_GAIN = 0.8  # –, k = 2ζ of each SOGI of the 3P filter when it starts (locks in ≈ 1 s at 3P) [PROPOSED]
RIPPLE_TRACK_GAIN = 0.1  # –, k of each SOGI once locked: little gain off the 3P line [PROPOSED]
RIPPLE_NARROW_S = 5.0  # s, the SOGIs narrow from RIPPLE_SOGI_GAIN to RIPPLE_TRACK_GAIN over this time [PROPOSED]
RIPPLE_MEAN_S = 20.0  # s, low-pass of ω_g,m taken off the filter's input, so that k may change [PROPOSED]
RIPPLE_ENGAGE_S = 0.5  # s, the 3P cancellation fades in and out over this time [PROPOSED]
EXTRA_MAX_AGE_S = 0.5  # s, a power phasor older than this is no longer synthesised [PROPOSED]
RELEASE_FADE_S = 5.0  # s, a stalled hold hands its torque over to the normal laws in this time [PROPOSED]


def speed_setpoint(params: TurbineParams, power_ref: np.ndarray) -> np.ndarray:
    """ω_set = clip(Ω_nom (P_r/P_rated)^{1/3}, ω_min, Ω_nom) in rad/s for references P_r in W."""
    ratio = np.maximum(power_ref, 0.0) / params.rated_power
    speed = np.maximum(params.omega_nom * np.cbrt(ratio), MIN_SPEED_FRACTION * params.omega_nom)  # np.clip's two
    return np.minimum(speed, params.omega_nom)


class FarmTurbineController(BenchmarkController):
    """The benchmark controller for n farm turbines, derating by speed set point (module docstring)."""

    def __init__(
        self, params: TurbineParams, n: int, power_reference: float, cancel_3p: bool = True, backend: str | None = None
    ):
        super().__init__(params, n, power_reference, backend=backend)
        # ``"numba"``: the zone logic, PI, damper and torque laws by ``plant_sim.farm.fast.control``, the same numbers
        self._farm_fast = fast_module("plant_sim.farm.fast") if self._fast is not None else None
        self.cancel_3p = cancel_3p  # the hold also cancels the 3P shaft torque (module docstring)
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
        p = params
        self._fast_constants = (p.dt, p.pitch_min_deg, p.pitch_max_deg, p.K_p, p.K_i, p.eta_gc, p.k_opt)
        self._fast_constants += tuple(float(v) for v in (self._bp_b[0], self._bp_b[2], self._bp_a[1], self._bp_a[2]))
        self._bp_state = np.zeros((2, n))  # transposed direct form II
        self._bp_ready = False
        self.damper_torque = np.zeros(n)  # N m, the damper's share of τ_g,r
        self.hold = np.zeros(n, dtype=bool)  # derating at held torque (module docstring)
        self.hold_asked = np.zeros(n, dtype=bool)  # the last reference asked for it
        self._asked_level = np.zeros(n)  # hold or cancellation asked, 0/1: where the cancellation's engagement heads
        self._any_asked = False  # any turbine asked to hold (set with the reference, read every tick)
        self._none_asked, self._no_level = np.zeros(n, dtype=bool), np.zeros(n)  # what a reference asking none sets
        self.tau_hold = np.zeros(n)  # N m, generator side, the held sum S = τ_g + B_g ω_g
        self._omega_g = np.zeros(n)  # rad/s, the last generator speed the controller used
        self._hold_set = np.zeros(n)  # rad/s, ω_set while in the hold
        self._release_from = np.zeros(n)  # rad/s, the hold's set point when the flag cleared
        self._hold_target = np.zeros(n)  # N m, the held sum S that tau_hold slews down to
        self._release_sum = np.zeros(n)  # N m, the held sum when the flag cleared
        self._handover = np.zeros(n)  # N m, the torque a stalled hold had when its flag cleared
        self._handover_left = np.zeros(n)  # s left of the fade from ``_handover`` to the normal laws
        self._handing_over = False
        self._ripple_state = np.zeros((4, n))  # v1, q1, v2, q2: the two SOGIs of the 3P filter
        self._ripple_running = False  # the filter runs while a turbine's cancellation is engaged or engaging
        self._ripple_on = np.zeros(n)  # – engagement of the cancellation, 0 … 1
        self._ripple_age = np.zeros(n)  # s since each turbine's cancellation began engaging
        self._ripple_mean = np.zeros(n)  # rad/s, ω_g,m low-passed over RIPPLE_MEAN_S
        self.ripple_torque = np.zeros(n)  # N m, generator side, the cancellation's share of τ_g,r
        self._extra: tuple[np.ndarray, np.ndarray, float] | None = None  # (C, ω, t_0) of the power to add
        self.extra_power = np.zeros(n)  # W, what the converter adds to the power this tick (ripple compensation)
        self.torque_slew = RAMP_FRACTION_PER_S * params.rated_power / (params.eta_gc * params.omega_nom) * params.dt

    def initialise(self, zone: np.ndarray, beta_ref: np.ndarray, tau_g_ref: np.ndarray) -> None:
        super().initialise(zone, beta_ref, tau_g_ref)
        self._bp_ready = False  # the damper's state is set from the first speed reading (steady state)
        self._ripple_running = False
        self._ripple_on[:] = 0.0
        self._ripple_age[:] = 0.0
        self.ripple_torque = np.zeros(self.n)

    def set_reference(
        self,
        power_ref: np.ndarray,
        hold_torque: np.ndarray | None = None,
        held_torque: np.ndarray | None = None,
        pitch_trim: np.ndarray | None = None,
        ripple: tuple[np.ndarray, np.ndarray, float] | None = None,
        cancel_3p: np.ndarray | None = None,
    ) -> None:
        """A new power reference per turbine (W) from the farm controller, followed at the ramp rate;
        ``hold_torque`` (n,) bool asks for the derating at held torque, ``held_torque`` (n,) N m caps the torque
        sum it holds (NaN: no cap); ``cancel_3p`` (n,) bool asks for the 3P cancellation without the derating
        (the hold asks for it too); ``pitch_trim`` (n, 3) deg is added to each blade's pitch command;
        ``ripple`` = (C (n,) complex W, ω (n,) rad/s, t_0 s) asks each turbine to add Re{C e^{jω(t − t_0)}} to
        its power (module docstring). None clears the last two."""
        trimmed = pitch_trim is not None and np.asarray(pitch_trim).any()
        self.pitch_trim = np.array(pitch_trim, dtype=float) if trimmed else None
        if ripple is None or not np.asarray(ripple[0]).any():
            self._extra = None
        else:  # the converter's lag α_gc/(s + α_gc) is taken out in advance: C (1 + jω/α_gc)
            phasor, rate, since = ripple
            lead = np.asarray(phasor, dtype=complex) * (1.0 + 1j * np.asarray(rate) / self.p.alpha_gc)
            self._extra = (lead, np.asarray(rate, dtype=float), float(since))
        self.power_ref_target = np.minimum(np.maximum(np.asarray(power_ref, dtype=float), 0.0), self.p.rated_power)
        self._ramping = True
        asks_none = (hold_torque is None or not np.any(hold_torque)) and (cancel_3p is None or not np.any(cancel_3p))
        if asks_none and not self.hold.any():
            # nothing asked and nothing held: no hold starts or is released, and what is asked stays nothing (the
            # lines below would find the same; these arrays are replaced, never written in place)
            self.hold_asked, self._asked_level, self._any_asked = self._none_asked, self._no_level, False
            return
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
            # a rotor below the hold's speed could not keep it (a lull): the climb's torque would keep it stalled,
            # so it goes back to the normal laws now, its torque fading over from where it is
            stalled = releasing & (self._omega_g < self._hold_set - self._hysteresis_at(self._hold_set))
            if stalled.any():
                own = self.tau_g_ref - self.damper_torque - self.ripple_torque
                self._handover = np.where(stalled, own, self._handover)
                self._handover_left = np.where(stalled, RELEASE_FADE_S, self._handover_left)
                self._handing_over = True
                self.hold = self.hold & ~stalled
        self.hold_asked = asked
        cancel = asked if cancel_3p is None else asked | np.asarray(cancel_3p, dtype=bool)
        self._asked_level = cancel.astype(float)
        self._any_asked = bool(cancel.any())
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
        cancelling = self.cancel_3p and (self._ripple_running or self._any_asked)
        if cancelling:  # the control laws read ω_g,m and P_g,m without the 3P swing and its cancellation
            ripple = self._ripple(omega_g_m)
            omega_g = omega_g_m - self._ripple_on * ripple
            p_g_m = p_g_m - (p.eta_gc * omega_g_m) * self.ripple_torque
        extra = self._extra_power(k)
        if extra is not None:  # nor the power they are asked to add for the farm
            p_g_m = p_g_m - extra
        if self._ramping:  # the reference moves towards the farm's at most ``ramp`` per tick
            step = np.minimum(np.maximum(self.power_ref_target - self.power_ref, -self.ramp), self.ramp)
            self.power_ref = self.power_ref + step
            self._ramping = bool(np.any(self.power_ref != self.power_ref_target))
            self.setpoint = speed_setpoint(p, self.power_ref)
            self._hysteresis = self._hysteresis_at(self.setpoint)
        if self.hold.any():
            self._hold_setpoint(omega_g)
        setpoint, hysteresis = self.setpoint, self._hysteresis
        # drive-train damper: band-pass of ω_g,m at the torsion mode (transposed direct form II; b1 = 0)
        b, z = self._bp_b, self._bp_state
        if not self._bp_ready:  # steady state of the band-pass for a constant input: zero output
            z[0] = z[1] = -b[0] * omega_g_m
            self._bp_ready = True
        if self._farm_fast is not None:
            region3, damper, base = self._fast_laws(omega_g, omega_g_m, p_g_m)
        else:
            region3, damper, base = self._laws(omega_g, omega_g_m, p_g_m)
        self._omega_g = omega_g
        self.damper_torque = damper
        if self.hold.any():
            # zone 0 in the hold: too little wind for the set point (or, on the way back, for the climb): let the
            # torque go steeply below the speed the rotor last held
            held_speed = np.where(self.hold_asked, setpoint, self._release_from)
            below = np.minimum(omega_g / np.maximum(held_speed - hysteresis, 1.0), 1.0)
            cube = below * below * below
            torque = self.tau_hold - p.B_g * omega_g
            base = np.where(self.hold, np.where(region3, torque, torque * cube * cube), base)  # (ω_g/ω_b)⁶
        if self._handing_over:
            left = self._handover_left
            base = base + (self._handover - base) * (left * (1.0 / RELEASE_FADE_S))
            self._handover_left = np.maximum(left - p.dt, 0.0)
            self._handing_over = bool(self._handover_left.any())
        self.tau_g_ref = base + damper
        if cancelling:
            self.tau_g_ref = self.tau_g_ref + self.ripple_torque
        if extra is not None:
            self.tau_g_ref = self.tau_g_ref + extra / (p.eta_gc * np.maximum(omega_g_m, 1.0))

    def _laws(
        self, omega_g: np.ndarray, omega_g_m: np.ndarray, p_g_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Zone logic, PI and the damper (updating zone, integrator, β_ref and the damper's state); returns
        (region 3, damper torque, the torque law's τ_g,r before hold, fade and damper)."""
        p, setpoint, hysteresis = self.p, self.setpoint, self._hysteresis
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
        b, a, z = self._bp_b, self._bp_a, self._bp_state
        damper = b[0] * omega_g_m + z[0]
        z[0] = z[1] - a[1] * damper
        z[1] = b[2] * omega_g_m - a[2] * damper
        base = np.where(region3, self.power_ref / (p.eta_gc * safe_omega), p.k_opt * omega_g * omega_g)
        return region3, damper, base

    def _fast_laws(
        self, omega_g: np.ndarray, omega_g_m: np.ndarray, p_g_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``_laws`` by ``plant_sim.farm.fast.control``: the same operations, row by row."""
        n = self.n
        zone, integrator = self.zone.copy(), self.integrator.copy()
        self.beta_ref, damper, base = np.empty(n), np.empty(n), np.empty(n)
        state = (zone, integrator, self.beta_ref, self._bp_state, damper, base)
        references = (
            np.ascontiguousarray(self.power_ref, dtype=float),
            np.ascontiguousarray(self.setpoint, dtype=float),
            np.ascontiguousarray(self._hysteresis, dtype=float),
            self.hold,
        )
        self._farm_fast.control(
            np.ascontiguousarray(omega_g, dtype=float), omega_g_m, p_g_m, state, references, self._fast_constants
        )
        self.zone, self.integrator = zone, integrator
        return zone.view(bool), damper, base

    def _extra_power(self, k: int) -> np.ndarray | None:
        """W to add to each turbine's power over tick k (held over the step: taken at its middle), or None; a
        phasor older than ``EXTRA_MAX_AGE_S`` (its supervisor has gone quiet) is dropped."""
        if self._extra is None:
            return None
        phasor, rate, since = self._extra
        age = (k + 0.5) * self.p.dt - since
        if age > EXTRA_MAX_AGE_S:
            self._extra = None
            self.extra_power = np.zeros(self.n)
            return None
        self.extra_power = (phasor * np.exp(1j * rate * age)).real
        return self.extra_power

    def _ripple(self, omega_g_m: np.ndarray) -> np.ndarray:
        """Advance the 3P filter on ω_g,m and set ``ripple_torque`` = −J_g v̇ (module docstring); returns v, the
        3P swing of ω_g,m (rad/s)."""
        p, dt = self.p, self.p.dt
        if not self._ripple_running:  # start from the filter's steady state for a constant speed
            self._ripple_state[:] = 0.0
            self._ripple_mean = omega_g_m.copy()
            self._ripple_running = True
        v1, q1, v2, q2 = self._ripple_state  # views: updated in place
        self._ripple_mean += (omega_g_m - self._ripple_mean) * (dt / RIPPLE_MEAN_S)
        w3 = (3.0 / p.N_g) * np.maximum(omega_g_m, 1.0)  # rad/s, the 3P frequency
        narrowed = np.minimum(self._ripple_age / RIPPLE_NARROW_S, 1.0)
        kw = (RIPPLE_SOGI_GAIN + (RIPPLE_TRACK_GAIN - RIPPLE_SOGI_GAIN) * narrowed) * w3
        v1 += dt * (kw * (omega_g_m - self._ripple_mean - v1) - w3 * q1)  # semi-implicit Euler: v, then q
        q1 += dt * w3 * v1
        dv2 = kw * (v1 - v2) - w3 * q2  # v̇ of the second stage, from its states: no numerical derivative
        v2 += dt * dv2
        q2 += dt * w3 * v2
        rate = dt / RIPPLE_ENGAGE_S
        self._ripple_on = np.clip(self._asked_level, self._ripple_on - rate, self._ripple_on + rate)
        self._ripple_age = np.where((self._ripple_on > 0.0) | (self._asked_level > 0.0), self._ripple_age + dt, 0.0)
        self.ripple_torque = -p.J_g * self._ripple_on * dv2
        self._ripple_running = bool(self._ripple_on.any())
        return v2
