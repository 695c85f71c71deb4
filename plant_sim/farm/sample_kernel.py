"""A farm sample's common ticks by one compiled call (``plant_sim.farm.fast.sub_steps``): its arguments gathered
from the farm's objects, and the state every object would hold after the sample's last tick written back.

What stays from sample to sample is kept (``SampleArguments``): the products of the fault factors and constants
the kernel reads (the aerodynamic gain, η_gc f_P, the drive train's K_dt f_K and B_dt f_B), the constants' tuples,
the flag arrays and the scratch arrays the kernel writes only where a flag says it acts. The fault factors are new
arrays whenever the turbines' faults change (``TurbineBatch._update_faults`` resets them, then applies the faults
acting), so the kept products are made again when any array they were made from is no longer the turbines' own
(``SampleArguments.current``): a fault that starts, ends or ramps reaches the kernel on the first compiled sample
after it. Arrays that leave the sample (the state, the frame's, the controller's and the wind sample's) stay new
every sample: the evaluation, the twins and the frames may keep them. ``batch`` in every function is the calling
``plant_sim.farm.plant.FarmBatch`` (not imported: this module is below it).
"""

from __future__ import annotations

import operator

import numpy as np

from plant_sim.farm.controller import (
    RIPPLE_ENGAGE_S,
    RIPPLE_MEAN_S,
    RIPPLE_NARROW_S,
    RIPPLE_SOGI_GAIN,
    RIPPLE_TRACK_GAIN,
    speed_setpoint,
)
from plant_sim.farm.wind import _THIRDS
from plant_sim.turbine.plant import _BETA_M1, _BETA_M2, _OMEGA_G_M1, _P_G_M, _PICK, ERROR_ONSET_S
from plant_sim.wind import WindSample
from wwcore.aero import _M_T
from wwcore.channels import SENSORS
from wwcore.farm_frames import FarmFrame
from wwcore.turbine_frames import TurbineFrame


class SampleArguments:
    """``sub_steps``'s arguments that stay between samples while the turbines' fault factors stay the same arrays."""

    def __init__(self, batch):
        tb, p, dt, n = batch.turbines, batch.p, batch.dt, batch.n
        self.sources = self._sources(batch)
        f = tb.faults
        self.aero = (_M_T, tb.dynamics.blade_gain * f.aero_factor, f.pitch_offset, p.radius)
        self.power_gain = p.eta_gc * f.power_factor
        stiffness = p.K_dt * f.stiffness_factor
        self.shaft = (stiffness, p.B_dt * f.damping_factor, p.N_g)
        self.mesh_flags = np.zeros(2, dtype=np.int8)  # [mesh active, error active (the kernel updates it)]
        mesh = (self.mesh_flags, tb._error_stage, tb._error_level, f.transmission_error, stiffness, f.eta_dt)
        self.mesh = (*mesh, tb.discrete.gamma_ext, (dt / ERROR_ONSET_S, p.N_g, 0.5 * dt))
        self.cancel_flags = np.zeros(3, dtype=np.int8)  # [cancel 3P, asked, running (the kernel updates it)]
        ripple = (dt, dt / RIPPLE_MEAN_S, 3.0 / p.N_g, RIPPLE_NARROW_S, RIPPLE_SOGI_GAIN)
        self.ripple_consts = (*ripple, RIPPLE_TRACK_GAIN - RIPPLE_SOGI_GAIN, dt / RIPPLE_ENGAGE_S, -p.J_g, p.eta_gc)
        # read by the kernel only where its flag acts: the 3P mean while the cancellation does not run, the phasor's
        # operands and output without a phasor
        self.idle_mean, self.no_extra = np.empty(n), np.empty(n)
        self.extra_off, self.extra_on = np.zeros(1, dtype=np.int8), np.ones(1, dtype=np.int8)
        self._blocks: dict[int, np.ndarray] = {}  # ticks → (3, ticks, n): P_r, ω_set and Ω_Δ,set of each tick

    @staticmethod
    def _sources(batch) -> tuple:
        """The arrays the kept arguments are made from or hold (the fault factors, the turbines' state of the wear's
        onset and the step's response to the wear's torque)."""
        tb = batch.turbines
        f = tb.faults
        sources = (f.aero_factor, f.pitch_offset, f.power_factor, f.stiffness_factor, f.damping_factor)
        return (*sources, f.transmission_error, f.eta_dt, tb.dynamics.blade_gain, tb._error_stage, tb._error_level)

    def current(self, batch) -> bool:
        """Whether every array the kept arguments were made from is still the turbines' own."""
        return all(map(operator.is_, self._sources(batch), self.sources)) and self.mesh[6] is (
            batch.turbines.discrete.gamma_ext
        )

    def reference_blocks(self, count: int, n: int) -> np.ndarray:
        """(3, count, n): each tick's P_r, ω_set and Ω_Δ,set, read by the kernel within the sample only."""
        blocks = self._blocks.get(count)
        if blocks is None:
            blocks = self._blocks[count] = np.empty((3, count, n))
        return blocks


def followed_references(batch, kept: SampleArguments, count: int) -> tuple:
    """(P_r (T, n), ω_set (T, n), Ω_Δ,set (T, n), whether P_r still moves after the sample) of the sample's ticks.
    The followed reference's path does not depend on the plant, so each tick's is computed ahead (``fast.ramp``).
    When P_r reaches its target on the first tick, every tick's set point is the first tick's: ω_set and Ω_Δ,set
    are elementwise functions of P_r, computed once on that row (the same numbers as on every row)."""
    c, p, n = batch.controller, batch.p, batch.n
    power_refs, setpoints, hysteresis = kept.reference_blocks(count, n)
    if not c._ramping:
        power_refs[:], setpoints[:], hysteresis[:] = c.power_ref, c.setpoint, c._hysteresis
        return power_refs, setpoints, hysteresis, False
    moving = batch.field._farm_fast.ramp(c.power_ref, c.power_ref_target, c.ramp, count, power_refs)
    if moving == 0:  # every tick's reference is the first tick's (``ramp`` copied it on)
        setpoints[:] = speed_setpoint(p, power_refs[0])
        hysteresis[:] = c._hysteresis_at(setpoints[0])
        return power_refs, setpoints, hysteresis, False
    setpoints[:] = speed_setpoint(p, power_refs)
    hysteresis[:] = c._hysteresis_at(setpoints)
    return power_refs, setpoints, hysteresis, moving == count


def run_compiled_sample(
    batch, kept: SampleArguments, states: np.ndarray | None, power: np.ndarray, shaft: np.ndarray | None
) -> FarmFrame:
    """``len(power)`` common ticks by ``plant_sim.farm.fast.sub_steps`` with the ``kept`` arguments (current); the
    last tick's frame, every object left as the ticks' calls would leave it."""
    tb, c, field, f, p, dt = batch.turbines, batch.controller, batch.field, batch.turbines.faults, batch.p, batch.dt
    fast = field._farm_fast
    count, n = power.shape
    k = batch.k
    wind = (field._table, field._slope, field._per_rad, field._offsets, field._base, field._hub, field._u3)
    wind += (field._mean, field._offset_now, field._offset_step, k - field._chunk_start)
    wind += (float(k % batch.ticks_per_sample),)
    sensors = (tb._draws, k % tb.noise_chunk, kept.power_gain, _PICK, tb.bias, _BETA_M1, _BETA_M2, f.torque_offset)
    sensors += (_OMEGA_G_M1, _P_G_M)
    zone, integrator, beta_ref, tau_g_ref = c.zone.copy(), c.integrator.copy(), c.beta_ref.copy(), c.tau_g_ref.copy()
    controller = (zone, integrator, beta_ref, c._bp_state, tau_g_ref, c._fast_constants)
    ramping = c._ramping
    power_refs, setpoints, hysteresis, still_ramping = followed_references(batch, kept, count)
    references = (c.power_ref, power_refs, setpoints, hysteresis, c.hold)
    pitch_add = f.pitch_command_offset if f.command_offset_active else None
    blades, torque, pitch_error = np.empty((3, n, 3))  # new arrays (rows of one): the objects keep them
    hub, mean, tau_aero, omega_g, damper, *frame = np.empty((8, n))
    y = np.empty((n, len(SENSORS)))
    last = (blades, hub, mean, torque, tau_aero, y, pitch_error, tb._quantities, omega_g, damper)
    frame = (*frame, np.empty(n, dtype=np.int8))
    shaft_args = None if shaft is None else (shaft, *kept.shaft)
    x = tb.x.copy()
    sums = (batch._scada_sum, batch._power_ref_sum)
    mesh_flags = kept.mesh_flags
    mesh_flags[0], mesh_flags[1] = f.mesh_active, tb._error_active
    cancel_flags = kept.cancel_flags
    cancel_flags[0], cancel_flags[1], cancel_flags[2] = c.cancel_3p, c._any_asked, c._ripple_running
    cancelled = c.cancel_3p and (c._ripple_running or c._any_asked)  # the kernel's test on its first tick
    if cancelled:  # the cancellation's filter runs from the first tick on: its state into new arrays
        ripple_on, ripple_age, ripple_torque = c._ripple_on.copy(), c._ripple_age.copy(), c.ripple_torque.copy()
        ripple_mean = c._ripple_mean if c._ripple_running else np.empty(n)
    else:  # the kernel reads none of them
        ripple_on, ripple_age, ripple_torque, ripple_mean = c._ripple_on, c._ripple_age, c.ripple_torque, kept.idle_mean
    cancel = (cancel_flags, c._ripple_state, ripple_mean, ripple_on, ripple_age, c._asked_level, ripple_torque)
    cancel += (kept.ripple_consts,)
    if c._extra is None:
        none = kept.no_extra
        extra = (kept.extra_off, none, none, none, (float(k), dt, 0.0, p.eta_gc), none)
    else:
        lead, rate, since = c._extra
        extra_power = np.empty(n)
        extra = (kept.extra_on, lead.real.copy(), lead.imag.copy(), rate, (float(k), dt, since, p.eta_gc), extra_power)
    fast.sub_steps(
        x,
        tb.discrete.shared,
        wind,
        field.turbulence_gain,
        kept.aero,
        sensors,
        controller,
        references,
        pitch_add,
        c.pitch_trim,
        sums,
        last,
        frame,
        states,
        power,
        shaft_args,
        kept.mesh,
        cancel,
        extra,
    )
    tb._error_active = bool(mesh_flags[1])
    if cancelled:  # its filter's state and outputs
        c._ripple_mean, c._ripple_on, c._ripple_age = ripple_mean, ripple_on, ripple_age
        c.ripple_torque, c._ripple_running = ripple_torque, bool(cancel_flags[2])
    if c._extra is not None:
        c.extra_power = extra_power
    # the state every object would hold after the last tick's advance
    k_last = k + count - 1
    tb.x, tb.k, batch.k = x, k + count, k + count
    tb.blade_torque, tb.tau_aero, tb.last_reading, tb._pitch_error = torque, tau_aero, y, pitch_error
    field._next_k = k + count
    field.rotor_wind = rotor = blades @ _THIRDS
    tb._wind_sample = WindSample(blades=blades, hub=hub, rotor=rotor, mean=mean)
    c.zone, c.integrator, c.beta_ref, c.tau_g_ref = zone, integrator, beta_ref, tau_g_ref
    c.damper_torque, c._omega_g = damper, omega_g
    if ramping:
        c.power_ref, c.setpoint, c._hysteresis = power_refs[-1].copy(), setpoints[-1].copy(), hysteresis[-1].copy()
        c._ramping = still_ramping
    turbines = TurbineFrame(k_last, k_last * dt, y, *frame)
    return batch._farm_frame(k_last, turbines)
