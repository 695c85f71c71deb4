"""The two plug-in roles of turbine supervision and what they exchange.

A **detector** (registry ``service.plugins.TURBINE_DETECTORS``) is built as
``factory(context=TurbineContext, options=dict)`` and has ``step(frame: TurbineFrame) -> Diagnosis``.
An **estimator** (``TURBINE_ESTIMATORS``) is built the same way and has
``step(frame: TurbineFrame, faulty: np.ndarray) -> Estimates``; ``faulty`` is the detector's verdict.
Both see only what a real supervisor sees: the sensor frame, never the plant's truth. Everything is batched
over n turbines (rows). See ``docs/plugins.md`` for a worked example.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from service.turbine.bank import BankDesign, ObserverBank, design_bank
from service.turbine.design_model import design_model
from wwcore.backend import fast_module, resolve_backend
from wwcore.channels import DIAGNOSIS_TARGETS, SENSOR_INDEX, SENSORS, SPEED_SENSORS, noise_std
from wwcore.turbine_frames import TurbineFrame
from wwcore.turbine_params import TurbineParams

SPEED_COLUMNS = np.array([SENSOR_INDEX[s] for s in SPEED_SENSORS])
POWER_COLUMNS = np.array([SENSOR_INDEX["p_g_m"], SENSOR_INDEX["tau_g_m"]])
BANK_COLUMNS = np.concatenate([SPEED_COLUMNS, POWER_COLUMNS])  # one gather: the 4 speeds, P_g,m, τ_g,m
# Below this generator torque (fraction of rated) P_g,m/τ_g,m is mostly noise: the power-speed channel then
# falls back to N_g × the mean rotor-speed reading.
POWER_SPEED_MIN_TORQUE = 0.05
# The power-speed channel's noise is mostly τ_g,m's relative to τ_g, so it falls as the torque rises: observer
# 5-pe is designed at these torques (fractions of rated, on the K ω² law of region 2), and the estimator uses the
# design nearest the torque reference (``power_speed_band``).
POWER_SPEED_DESIGN_TORQUES = (0.15, 0.35, 0.8)
# Their random walk of the aerodynamic torque, measured as DESIGN_Q_UNKNOWN is below at the wind where region 2
# has each torque (5.8, 8.0, 11.5 m/s): std of 1-s increments / √100 = 3.8e3, 7.6e3, 1.35e4 N m (at 9.5 m/s:
# 1.05e4). The torque changes faster as the wind rises, and a filter that expects slower changes lags them.
POWER_SPEED_DESIGN_Q = (3.8e3**2, 7.6e3**2, 1.35e4**2)  # (N m)² per tick
# In region 3 the torque changes far faster still (1.4e4 at 11.5 m/s, 2.4e4 at 14, 7.9e4 at 18, 4.8e5 at 24 m/s),
# and no random walk fits all of it: there 5-pe is the rigid drive train on the three channels
# (``uio.design_rigid``), designed at rated torque, which needs no model of the torque at all.
POWER_SPEED_REGION3 = "5-pe-r3"
# The torque bands of ``power_speed_band``, after the design bands 0, 1, 2 (``POWER_SPEED_DESIGN_TORQUES`` order):
# region 3 (the controller's zone 1), then region 1 (the torque reference below ``POWER_SPEED_MIN_TORQUE`` × rated,
# whatever the zone), where the power-speed channel is N_g × the rotor-speed sensors' mean. Who serves each band
# is a table of the user's: the estimator's ``bank.power_speed_estimate_observers``, the detector's
# ``POWER_SPEED_DETECTOR_DESIGNS``.
POWER_SPEED_REGION3_BAND = len(POWER_SPEED_DESIGN_TORQUES)
POWER_SPEED_REGION1_BAND = len(POWER_SPEED_DESIGN_TORQUES) + 1
POWER_SPEED_BANDS = POWER_SPEED_REGION1_BAND + 1
# The 5-pe design (index into ``BankDesign.power_speed``) the detector's isolation, clearing and arbitration use in
# each band: its own in the design and region-3 bands, 5-pe15 in region 1 (a design at region 1's own random walk
# moved the flags there, decision N-15; the channel is the rotor-speed mean, which 5-pe15 weighs as 1.27 rad/s).
POWER_SPEED_DETECTOR_DESIGNS = (*range(len(POWER_SPEED_DESIGN_TORQUES) + 1), 0)

# Design process noise of the observers (per step): the drive-train model is exact up to the efficiency fault
# and the converter's torque offset, so Q is small.
DESIGN_Q = np.diag([1e-8, 1e-6, 1e-12, 1.0])  # (rad/s)², (rad/s)², rad², (N m)²
# Observer 5 (a Kalman filter) models the aerodynamic torque as a random walk. Its variance per tick is
# the one that reproduces how the benchmark turbine's aerodynamic torque spreads over 1 s, the time scale the
# wind estimate resolves (0.3 Hz), in 12 % turbulence: fault-free simulation, torque low-passed at 1 Hz,
# std of 1-s increments / √100 ticks = 9.7e3 N m (at 10 s: 6.9e3; unfiltered per tick: 1.0e4).
DESIGN_Q_UNKNOWN = 1e4**2  # (N m)² per tick


@dataclass
class Diagnosis:
    """A detector's verdict for n turbines."""

    faulty: np.ndarray  # (n, len(DIAGNOSIS_TARGETS)) bool, wwcore.channels.DIAGNOSIS_TARGETS order
    margins: np.ndarray | None = None  # (n, m) test statistic / threshold of each named residual; > 1 trips
    margin_names: tuple[str, ...] = ()  # names of the m residuals
    # (n, len(DIAGNOSIS_TARGETS)) bool or None: ``faulty`` plus targets under suspicion while an isolation is
    # under way; the supervisor gives the estimator this instead of ``faulty`` (events come from ``faulty`` only)
    suspect: np.ndarray | None = None


@dataclass
class Estimates:
    """An estimator's outputs for n turbines."""

    valid: np.ndarray  # (n,) bool, the controller may use them
    omega_r: np.ndarray  # (n,) rad/s
    omega_g: np.ndarray  # (n,) rad/s
    wind: np.ndarray  # (n,) m/s, the fault-tolerant estimate (FTE)
    selected: np.ndarray  # (n,) int, index of the observer in use (−1 none)
    observer_names: tuple[str, ...] = ()
    wind_reference: np.ndarray | None = None  # (n,) m/s, the non-fault-tolerant estimate (NFTE), if any


def empty_diagnosis(n: int) -> Diagnosis:
    return Diagnosis(np.zeros((n, len(DIAGNOSIS_TARGETS)), dtype=bool))


class TurbineContext:
    """What every turbine algorithm may know: the turbine's parameters, the sensors' noise, the batch size.

    It also owns the observer bank of seed 000, designed once and stepped at most once per tick however many
    algorithms ask for it.

    ``backend`` (``wwcore.backend``): with ``"numba"``, ``fast`` is ``service.turbine.fast``, whose kernels the
    bank and the built-in algorithms use for their per-tick arithmetic (the same numbers); else ``fast`` is None.
    """

    def __init__(self, params: TurbineParams, n: int, noise_convention: str = "sigma", backend: str | None = None):
        self.params = params
        self.backend = resolve_backend(backend)
        self.fast = fast_module("service.turbine.fast") if self.backend == "numba" else None
        self.n = n
        self.dt = params.dt
        self.noise_convention = noise_convention
        self.sensor_sigma = {c.name: noise_std(c, noise_convention) for c in SENSORS}
        self._bank: ObserverBank | None = None
        self._bank_tick: int | None = None
        self._speed: np.ndarray | None = None  # the four speed readings of tick _bank_tick
        # the estimate of the speed sensors' calibration offsets that a detector keeps (``fdi``, an
        # ``adaptive.HealthySpread`` whose ``offset`` (n, 4) is updated in place; None: none): ``speed_offset``
        self.speed_calibration = None

    @property
    def speed_offset(self) -> np.ndarray | None:
        """(n, 4) calibration offsets of the speed sensors, subtracted from the bank's inputs (None: none); the
        object is held rather than its array, a view that a copy of the context would not keep
        (``wwcore.planes``)."""
        return None if self.speed_calibration is None else self.speed_calibration.offset

    @cached_property
    def bank_design(self) -> BankDesign:
        return _cached_bank_design(self.params, self.noise_convention)

    @cached_property
    def power_speed_min_torque(self) -> float:
        """``POWER_SPEED_MIN_TORQUE`` × the rated torque, N m: below it the power-speed channel is not used."""
        return POWER_SPEED_MIN_TORQUE * self.params.rated_torque

    def bank(self, frame: TurbineFrame) -> ObserverBank:
        """The observer bank advanced to ``frame`` (initialised on the first frame)."""
        if self._bank is None:
            y = self._bank_inputs(frame)
            self._bank = ObserverBank(self.bank_design, self.n, fast=self.fast)
            self._bank.initialise(static_state_guess(self.params, self._speed, frame.tau_g_ref), y)
            self._bank_tick = frame.k
            self._bank.step(y, frame.tau_g_ref)
        elif self._bank_tick != frame.k:
            if self.fast is not None:  # ``_bank_inputs`` and the step by one kernel call
                self._speed = self._bank.step_readings(self._input_columns(frame), self.speed_offset, frame.tau_g_ref)
            else:
                self._bank.step(self._bank_inputs(frame), frame.tau_g_ref)
            self._bank_tick = frame.k
        return self._bank

    def steady_bank(self, k: int) -> ObserverBank | None:
        """The compiled bank where its step to tick ``k`` is its kept call (``fast.bank_tick_kept``: it has taken its
        first frame and not this one, and its transient update matrices are used up), which a caller's kernel may
        make (``fast_supervisor``; then ``bank_ticked``); else None."""
        bank = self._bank
        if bank is None or bank.kept is None or self._bank_tick == k:
            return None
        return bank

    def bank_ticked(self, k: int, speed: np.ndarray) -> None:
        """The bank stepped to tick ``k`` by a caller's kernel (``fast_supervisor``; ``ObserverBank.ticked``), with
        ``speed`` the tick's speed readings (``speed_readings``)."""
        self._bank_tick, self._speed = k, speed

    def _bank_inputs(self, frame: TurbineFrame) -> np.ndarray:
        """The bank's input columns (``bank_design.inputs``: 4 speeds, the power-speed channel) for this frame;
        keeps the speed readings aside. The compiled path gathers them inside its step (``fast.bank_tick``, the same
        numbers: ``tests/test_fast_kernels.py``) and calls this on the first frame only."""
        read = frame.sensors.take(BANK_COLUMNS, axis=1)  # (n, 6); column 4 becomes the power-speed channel
        read[:, 4] = power_speed(read[:, 4], read[:, 5], read, self.params)
        offset = self.speed_offset
        self._speed = read[:, :4].copy() if offset is not None else read[:, :4]
        if offset is not None:
            read[:, :4] -= offset
        return read[:, :5]

    def _input_columns(self, frame: TurbineFrame) -> tuple:
        """The compiled bank inputs' arguments (sensors, columns, threshold, N_g, η_gc): ``fast_bank.bank_inputs``."""
        p = self.params
        return frame.sensors, BANK_COLUMNS, self.power_speed_min_torque, p.N_g, p.eta_gc

    def speed_readings(self, frame: TurbineFrame) -> np.ndarray:
        """``frame.sensors[:, SPEED_COLUMNS]`` (n, 4), gathered once per tick with the bank's step (read-only)."""
        self.bank(frame)
        return self._speed


def power_speed(power: np.ndarray, torque: np.ndarray, speed: np.ndarray, p: TurbineParams) -> np.ndarray:
    """Generator speed from the electrical power and torque readings, ω_g = P_g,m / (η_gc τ_g,m), rad/s.

    P_g = η_gc ω_g τ_g (PARAMETERS.md a.2) holds whatever the speed sensors do, so this is an analytical
    generator-speed channel that survives faults of both generator-speed sensors. Its noise is that of τ_g,m
    relative to τ_g (plus P_g,m's): ≈ 0.6 % of ω_g half-way up region 2 against 1.6 % for one rotor-speed
    sensor. Below ``POWER_SPEED_MIN_TORQUE`` × rated torque the ratio is mostly noise and N_g × the mean
    rotor-speed reading (``speed`` columns 0, 1) stands in.
    """
    low = torque < POWER_SPEED_MIN_TORQUE * p.rated_torque
    if low.any():
        fallback = p.N_g * 0.5 * (speed[:, 0] + speed[:, 1])
        return np.where(low, fallback, power / (p.eta_gc * np.where(low, 1.0, torque)))
    return power / (p.eta_gc * torque)


def power_speed_name(torque_fraction: float) -> str:
    """Name of the 5-pe observer designed at ``torque_fraction`` × rated torque: "5-pe35" at 0.35."""
    return f"5-pe{round(100 * torque_fraction)}"


def power_speed_band(torque: np.ndarray, p: TurbineParams, zone: np.ndarray | None = None) -> np.ndarray:
    """Torque band of each row (n,), the key of the tables that say which observer serves it with both
    generator-speed sensors distrusted: ``POWER_SPEED_REGION1_BAND`` where the torque reference ``torque`` (N m) is
    below ``POWER_SPEED_MIN_TORQUE`` × rated (the power-speed channel is then N_g × the rotor-speed sensors' mean,
    ``power_speed``), else ``POWER_SPEED_REGION3_BAND`` where the controller's ``zone`` is region 3 (1), else the
    index into ``POWER_SPEED_DESIGN_TORQUES`` of the design nearest the torque on a log scale (NaN: the last)."""
    edges = np.sqrt(np.multiply(POWER_SPEED_DESIGN_TORQUES[:-1], POWER_SPEED_DESIGN_TORQUES[1:])) * p.rated_torque
    band = np.searchsorted(edges, torque)
    if zone is not None:
        band = np.where(zone == 1, POWER_SPEED_REGION3_BAND, band)
    return np.where(torque < POWER_SPEED_MIN_TORQUE * p.rated_torque, POWER_SPEED_REGION1_BAND, band)


def power_speed_sigma(sigma: dict[str, float], p: TurbineParams, torque_fraction: float) -> float:
    """Noise σ of ``power_speed`` (rad/s) at ``torque_fraction`` × rated torque on the K ω² law of region 2, from
    the σ of P_g,m and τ_g,m by first-order propagation."""
    torque = torque_fraction * p.rated_torque
    omega_g = p.omega_nom * np.sqrt(torque_fraction)
    power = p.eta_gc * omega_g * torque
    return float(omega_g * np.hypot(sigma["p_g_m"] / power, sigma["tau_g_m"] / torque))


def static_state_guess(p: TurbineParams, y_speed: np.ndarray, tau_g: np.ndarray) -> np.ndarray:
    """[ω_r, ω_g, θ_Δ, τ_g] from one sample, assuming the drive train at rest (used to start observers)."""
    omega_r = y_speed[:, :2].mean(axis=1)
    omega_g = y_speed[:, 2:].mean(axis=1)
    shaft = p.N_g * (p.B_g * omega_g + tau_g) / p.eta_dt
    theta = (shaft - p.B_dt * (omega_r - omega_g / p.N_g)) / p.K_dt
    return np.column_stack([omega_r, omega_g, theta, tau_g])


_BANKS: dict[tuple, BankDesign] = {}


def _cached_bank_design(params: TurbineParams, convention: str) -> BankDesign:
    key = (params, convention)
    if key not in _BANKS:
        all_sigma = {c.name: noise_std(c, convention) for c in SENSORS}
        sigma = {name: all_sigma[name] for name in SPEED_SENSORS}
        torques, qs = POWER_SPEED_DESIGN_TORQUES, POWER_SPEED_DESIGN_Q
        power_speed = [
            (power_speed_name(t), power_speed_sigma(all_sigma, params, t), q) for t, q in zip(torques, qs, strict=True)
        ]
        power_speed.append((POWER_SPEED_REGION3, power_speed_sigma(all_sigma, params, 1.0), None))
        _BANKS[key] = design_bank(
            design_model(params), sigma, DESIGN_Q, DESIGN_Q_UNKNOWN, power_speed, single_generator=True
        )
    return _BANKS[key]
