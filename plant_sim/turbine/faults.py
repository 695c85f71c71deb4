"""Fault schedule of a turbine batch, compiled into per-row arrays the step code applies cheaply.

Faults change state only at a few ticks (start, end, and during ramps), so the arrays below are rebuilt from
the active fault list at those ticks only; every other tick reads them as they are.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from plant_sim.turbine.mismatch import RowMismatch, nominal
from wwcore.channels import N_SENSORS, SENSOR_INDEX, Component
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.turbine_params import TurbineParams

PITCH_COMPONENTS = {Component.PITCH_ACTUATOR_1: 0, Component.PITCH_ACTUATOR_2: 1, Component.PITCH_ACTUATOR_3: 2}


@dataclass
class FaultState:
    """The effect of every active fault on every row of the batch, at the current tick.

    ``healthy`` holds the healthy plant's own parameters (``plant_sim.turbine.mismatch``): with no fault active the
    pitch actuators, drive-train factors and aerodynamic factor are the plant's, not the design model's.
    """

    n: int
    params: TurbineParams
    healthy: RowMismatch | None = None
    gain: np.ndarray = field(init=False)  # (n, N_SENSORS) multiplies truth + noise
    offset: np.ndarray = field(init=False)  # (n, N_SENSORS) added to the reading
    drift_rate: np.ndarray = field(init=False)  # (n, N_SENSORS) unit/s, times (t − drift_start)
    drift_start: np.ndarray = field(init=False)  # (n, N_SENSORS) s
    noise_scale: np.ndarray = field(init=False)  # (n, N_SENSORS) multiplies the noise σ
    fixed: np.ndarray = field(init=False)  # (n, N_SENSORS) bool, reading replaced by fixed_value
    fixed_value: np.ndarray = field(init=False)
    stuck: np.ndarray = field(init=False)  # (n, N_SENSORS) bool, reading held at stuck_value
    stuck_value: np.ndarray = field(init=False)
    pitch_a0: np.ndarray = field(init=False)  # (n, 3) ω_n² of each pitch actuator, 1/s²
    pitch_a1: np.ndarray = field(init=False)  # (n, 3) 2ζω_n, 1/s
    pitch_offset: np.ndarray = field(init=False)  # (n, 3) deg added to each blade's actual pitch
    torque_offset: np.ndarray = field(init=False)  # (n,) N m added to the converter's torque reference
    eta_dt: np.ndarray = field(init=False)  # (n,) drive-train efficiency
    aero_factor: np.ndarray = field(init=False)  # (n,) multiplies the aerodynamic torque (the plant's s ρ/ρ_0)
    stiffness_factor: np.ndarray = field(init=False)  # (n,) multiplies K_dt
    damping_factor: np.ndarray = field(init=False)  # (n,) multiplies B_dt
    power_factor: np.ndarray = field(init=False)  # (n,) multiplies the electrical power output (farm debris)
    pitch_command_offset: np.ndarray = field(init=False)  # (n, 3) deg added to each blade's actuator command
    transmission_error: np.ndarray = field(init=False)  # (n,) rad, 3P transmission error amplitude (farm fault 3)
    sensor_faults_active: bool = False
    drift_active: bool = False
    command_offset_active: bool = False
    mesh_active: bool = False

    def __post_init__(self) -> None:
        if self.healthy is None:
            self.healthy = nominal(self.params, self.n)
        self.reset()

    def reset(self) -> None:
        n, m = self.n, self.healthy
        self.gain = np.ones((n, N_SENSORS))
        self.offset = np.zeros((n, N_SENSORS))
        self.drift_rate = np.zeros((n, N_SENSORS))
        self.drift_start = np.zeros((n, N_SENSORS))
        self.noise_scale = np.ones((n, N_SENSORS))
        self.fixed = np.zeros((n, N_SENSORS), dtype=bool)
        self.fixed_value = np.zeros((n, N_SENSORS))
        self.stuck = np.zeros((n, N_SENSORS), dtype=bool)
        self.stuck_value = np.zeros((n, N_SENSORS))
        self.pitch_a0 = m.pitch_a0
        self.pitch_a1 = m.pitch_a1
        self.pitch_offset = np.zeros((n, 3))
        self.torque_offset = np.zeros(n)
        self.eta_dt = np.full(n, self.params.eta_dt)
        self.aero_factor = m.aero_factor
        self.stiffness_factor = m.stiffness_factor.copy()
        self.damping_factor = m.damping_factor.copy()
        self.power_factor = np.ones(n)
        self.pitch_command_offset = np.zeros((n, 3))
        self.transmission_error = np.zeros(n)
        self.sensor_faults_active = False
        self.drift_active = False
        self.command_offset_active = False
        self.mesh_active = False

    def apply(self, fault: FaultSpec, rows: np.ndarray, f: float, held: np.ndarray | None) -> None:
        """Add one fault at intensity f ∈ (0, 1] to ``rows``; ``held`` is a stuck fault's frozen reading."""
        p = self.params
        if fault.target in SENSOR_INDEX:
            ch = SENSOR_INDEX[fault.target]
            self.sensor_faults_active = True
            value = fault.value
            match fault.kind:
                case FaultKind.FIXED:
                    self.fixed[rows, ch] = True
                    self.fixed_value[rows, ch] = value
                case FaultKind.GAIN:
                    self.gain[rows, ch] *= 1.0 + f * (value - 1.0)
                case FaultKind.OFFSET:
                    self.offset[rows, ch] += f * value
                case FaultKind.DRIFT:
                    self.drift_active = True
                    self.drift_rate[rows, ch] += f * value
                    self.drift_start[rows, ch] = fault.start_s
                case FaultKind.STUCK:
                    self.stuck[rows, ch] = True
                    self.stuck_value[rows, ch] = held
                case FaultKind.NOISE:
                    self.noise_scale[rows, ch] *= 1.0 + f * (value - 1.0)
            return
        match fault.kind:
            case FaultKind.PITCH_DYNAMICS:
                # Fault 7 of the benchmark: the actuator's state-space matrices are interpolated linearly
                # between the healthy plant's and faulty with the fault signal f (PARAMETERS.md a.2).
                blade = PITCH_COMPONENTS[Component(fault.target)]
                a0_fault, a1_fault = fault.omega_n**2, 2.0 * fault.zeta * fault.omega_n
                healthy_a0, healthy_a1 = self.healthy.pitch_a0[rows, blade], self.healthy.pitch_a1[rows, blade]
                self.pitch_a0[rows, blade] += f * (a0_fault - healthy_a0)
                self.pitch_a1[rows, blade] += f * (a1_fault - healthy_a1)
            case FaultKind.PITCH_OFFSET:
                self.pitch_offset[rows, PITCH_COMPONENTS[Component(fault.target)]] += f * fault.value
            case FaultKind.TORQUE_OFFSET:
                self.torque_offset[rows] += f * fault.value
            case FaultKind.EFFICIENCY:
                self.eta_dt[rows] += f * (fault.value - p.eta_dt)
            case FaultKind.OFFSET if fault.target in PITCH_COMPONENTS:
                # Farm fault 2, pitch misalignment: blade k's actuator holds it ``value`` deg off the collective
                # command; its encoders measure the true blade angle, so they see the offset (docs/farm.md).
                self.command_offset_active = True
                self.pitch_command_offset[rows, PITCH_COMPONENTS[Component(fault.target)]] += f * fault.value
            case FaultKind.DEBRIS:
                # Farm fault 1 as the farm benchmark defines it: the power output falls to ``value`` (0.97) of what
                # the generator delivers, at unchanged rotor speed and torque (seed 001, Section 3.3: the rotor
                # speed "is not affected by the debris"; eq. (24) restores the output by 1/0.97). A loss of
                # aerodynamic efficiency instead would be absorbed by the pitch loop below the available power
                # and is indistinguishable from a 1 % lower wind (docs/farm.md).
                self.power_factor[rows] *= 1.0 + f * (fault.value - 1.0)
            case FaultKind.DRIVETRAIN_WEAR:
                # Farm fault 3: a worn planetary stage (three planets, carrier on the main shaft) with a transmission
                # error at the planet-pass frequency 3P, e(ψ) = e_0 cos 3ψ on the low-speed shaft, e_0 = ``value``
                # in mrad: the spring twists by θ_Δ − e(ψ) (docs/farm.md, plant_sim.turbine.plant).
                self.mesh_active = True
                self.transmission_error[rows] += f * fault.value * 1e-3
            case _:
                raise ValueError(f"the turbine plant cannot apply a {fault.kind.value} fault on {fault.target}")


@dataclass
class ScheduledFault:
    """A fault of the batch with the ticks at which it starts and ends."""

    spec: FaultSpec
    rows: np.ndarray  # batch rows it acts on
    start_tick: int
    end_tick: int | None  # None: until the run ends
    held: np.ndarray | None = None  # a stuck fault's reading frozen at its first tick (len(rows),)

    def intensity(self, k: int, dt: float) -> float:
        if k < self.start_tick or (self.end_tick is not None and k >= self.end_tick):
            return 0.0
        return self.spec.intensity(max(k * dt, self.spec.start_s))

    def next_change(self, k: int, dt: float) -> int:
        """The first tick after k at which ``changing`` may be true (every tick while ramping)."""
        if k < self.start_tick:
            return self.start_tick
        if self.spec.ramp_s > 0.0 and (self.end_tick is None or k < self.end_tick):
            return k + 1
        if self.end_tick is not None and k < self.end_tick:
            return self.end_tick
        return np.iinfo(np.int64).max

    def changing(self, k: int, dt: float) -> bool:
        """True when the fault's intensity at tick k may differ from tick k−1."""
        if k == self.start_tick or k == self.end_tick:
            return True
        if self.spec.ramp_s <= 0.0 or k < self.start_tick:
            return False
        t = k * dt
        end = self.spec.end_s if self.spec.end_s is not None else np.inf
        return t <= self.spec.start_s + self.spec.ramp_s + dt or t >= end - self.spec.ramp_s - dt
