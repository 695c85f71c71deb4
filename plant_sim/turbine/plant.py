"""A batch of benchmark turbines following the step contract of ``wwcore.stepping``.

Integration scheme (stated once, tested in ``tests/test_turbine_plant.py``): at the controller's sample time
Ts = 0.01 s the controller outputs, the wind sample and the aerodynamic torque (evaluated at the tick's state)
are held over the step, and the then-linear drive train, converter and pitch actuators are advanced exactly by
their matrix exponential (``dynamics.DiscreteStep``). The 4.5 Hz torsion mode (ωTs = 0.29), the converter
(α_gc Ts = 0.5) and the pitch actuators (ω_n Ts = 0.11) are thus resolved without numerical damping; the only
approximation is the hold of τ_r, whose change within 10 ms is below 0.5 % of its value (a test compares a
fine RK4 integration of the continuous model). Holding τ_r over the step is also the zero-order hold on the
unknown input that the observers' discrete design model assumes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from plant_sim.turbine.controller import BenchmarkController
from plant_sim.turbine.dynamics import (
    AZIMUTH,
    N_STATES,
    OMEGA_G,
    OMEGA_R,
    PITCH,
    TAU_G,
    THETA,
    DiscreteStep,
    TurbineDynamics,
)
from plant_sim.turbine.faults import FaultState, ScheduledFault
from plant_sim.turbine.mismatch import resolve
from plant_sim.turbine.trim import PlantAero, trim
from plant_sim.wind import WindField, WindSample
from wwcore.backend import fast_module, resolve_backend
from wwcore.channels import SENSOR_INDEX, SENSORS, noise_std
from wwcore.events import Event, EventType
from wwcore.planes import Planes
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.scenario.mismatch import Mismatch
from wwcore.scenario.turbine import TurbinePlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_frames import TurbineFrame, TurbineRefs
from wwcore.turbine_params import BENCHMARK, TurbineParams

# Measured quantities, in the order the sensor channels pick them (wwcore.channels.SENSORS[i].quantity).
_QUANTITIES = ("omega_r", "omega_g", "v_hub", "beta_1", "beta_2", "beta_3", "tau_g", "p_g")
_PICK = np.array([_QUANTITIES.index(c.quantity) for c in SENSORS])
_BETA_M1 = np.array([SENSOR_INDEX[f"beta_{i}_m1"] for i in (1, 2, 3)])
_BETA_M2 = np.array([SENSOR_INDEX[f"beta_{i}_m2"] for i in (1, 2, 3)])
_BETA_M12 = np.concatenate([_BETA_M1, _BETA_M2])
_OMEGA_G_M1 = SENSOR_INDEX["omega_g_m1"]
_P_G_M = SENSOR_INDEX["p_g_m"]
_CONTROL_COLUMNS = (_OMEGA_G_M1, _P_G_M)  # the controller's readings: ω_g,m1 and P_g,m
_MEASURE_COLUMNS = np.concatenate([_PICK, _BETA_M1, _BETA_M2])  # the measurement kernel's: pick, β_m1, β_m2
ERROR_ONSET_S = 0.25  # s, time constant of each of the two lags through which a transmission error develops (fault 3)


def row_streams(seed: int, run: int, turbine: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent random streams (wind, sensor noise) of one turbine in one Monte Carlo run.

    They depend only on (seed, run, turbine), never on which other rows share the batch.
    """
    wind_seq, noise_seq = np.random.SeedSequence(seed, spawn_key=(run, turbine)).spawn(2)
    return np.random.default_rng(wind_seq), np.random.default_rng(noise_seq)


class TurbineBatch(Planes):
    """n independent benchmark turbines (rows = Monte Carlo runs × turbines), one tick per step call.

    ``mismatch`` (a scenario's ``[mismatch]`` section) makes the plant differ from the design model: its rows get
    their own aerodynamics, drive train, pitch actuators, sensor noise and calibration biases (``self.mismatch``,
    per row, ``plant_sim.turbine.mismatch``); the turbine's controller keeps the design values, as a real one would.

    ``backend`` (``wwcore.backend``): ``"numba"`` runs the common tick through ``plant_sim.turbine.fast``, with the
    same results; ``None`` takes the process default.
    """

    # the one-kernel measurement's outputs (``_measure_arguments``) are planes of two blocks (``wwcore.planes``)
    PLANES: ClassVar[dict[str, tuple]] = {
        "_per_blade": (("blade_torque", 1), ("_pitch_error", 2)),
        "_per_row": (("tau_aero", 1),),
    }

    def __init__(
        self,
        plant: TurbinePlant,
        wind: WindSpec,
        faults: Sequence[FaultSpec],
        *,
        seed: int,
        runs: Sequence[int] = (0,),
        turbines: Sequence[int] = (1,),
        params: TurbineParams = BENCHMARK,
        wind_field: object | None = None,
        noise_chunk: int = 1000,
        fault_free_twins: bool = False,
        mismatch: Mismatch | None = None,
        backend: str | None = None,
    ):
        self.p = params
        self.backend = resolve_backend(backend)
        self._fast = fast_module("plant_sim.turbine.fast") if self.backend == "numba" else None
        # the noise blocks' draws: numpy's numbers from a compiled loop (``wwcore.random_fast``) with numba
        self._random = fast_module("wwcore.random_fast") if self.backend == "numba" else None
        self.dt = params.dt
        self.k = 0
        run_of_row = np.repeat(np.asarray(runs, dtype=int), len(turbines))
        turbine_of_row = np.tile(np.asarray(turbines, dtype=int), len(runs))
        copies = 2 if fault_free_twins else 1
        # Twin rows (the second half, when asked for) share their run's wind and noise but no fault ever reaches
        # them: the same run without faults, for scoring what the faults cost.
        self.twin_of_row = np.repeat(np.arange(copies) == 1, len(run_of_row))
        self.run_of_row = np.tile(run_of_row, copies)
        self.turbine_of_row = np.tile(turbine_of_row, copies)
        self.n = len(self.run_of_row)
        streams = [row_streams(seed, int(r), int(t)) for r, t in zip(self.run_of_row, self.turbine_of_row, strict=True)]
        self._noise_rngs = [noise for _, noise in streams]
        self._noise_rows = self.n // copies  # rows that draw noise; twins reuse their run's
        self.wind = (
            wind_field
            if wind_field is not None
            else WindField(wind, params, [w for w, _ in streams], self.dt, backend=self.backend)
        )
        self.dynamics = TurbineDynamics(params)
        self.discrete = DiscreteStep(params, self.n)
        self.mismatch = resolve(mismatch, params, seed, self.run_of_row, self.turbine_of_row)
        self._tsr_shift = self.mismatch.tsr_shift if self.mismatch.shifted else None
        self.sigma = np.array([noise_std(c, plant.noise_convention) for c in SENSORS])
        self.bias = np.array([c.noise_mean for c in SENSORS])
        if not self.mismatch.noise_nominal:  # σ per row and sensor, shaped to scale a (rows, ticks, sensors) block
            self.sigma = (self.sigma * self.mismatch.noise_scale[: self.n // copies])[:, None, :]
        if not self.mismatch.bias_nominal:
            self.bias = self.bias + self.mismatch.bias
        self.noise_chunk = noise_chunk
        # Noise blocks of noise_chunk ticks, refilled and σ-scaled in place: a fresh 10-MB array per block costs page
        # faults, and scaling through a transposed view took half as long again as the drawing. The draws of the
        # rows with their own stream; twin rows repeat their run's numbers tick by tick in ``_tick_noise``.
        self._draws = np.empty((self._noise_rows, noise_chunk, len(SENSORS)))
        self._tick_noise = np.empty((self.n, len(SENSORS)))
        self._noise_drawn = False
        self._quantities = np.empty((self.n, len(_QUANTITIES)))  # refilled every tick, read through _PICK
        self.faults = FaultState(self.n, params, self.mismatch)
        self.schedule: list[ScheduledFault] = []
        self._next_change = 0  # tick at which the fault arrays may next change
        for fault in faults:
            self.inject(fault)
        self.controller = BenchmarkController(params, self.n, plant.power_reference_w, backend=self.backend)
        self.x = np.zeros((self.n, N_STATES))
        self._trim(float(np.interp(0.0, *zip(*wind.mean, strict=True))), plant.power_reference_w)
        self.discrete.update(self.faults)
        self.tau_aero = np.zeros(self.n)
        self._events: list[Event] = []
        self.last_reading = np.zeros((self.n, len(SENSORS)))
        self._pitch_error = np.zeros((self.n, 3))
        self.blade_torque = np.zeros((self.n, 3))  # N m, τ_r,i of each blade at the current tick
        self._error_level = np.zeros(self.n)  # rad, transmission error amplitude acting now (farm fault 3)
        self._error_stage = np.zeros(self.n)  # rad, first stage of its onset filter
        self._error_active = False
        self._sample: WindSample | None = None
        # the whole measurement by one kernel (``_fast_measure_frame``) where the plant samples its own ``WindField``
        # (not a farm's ``FarmWindField``, a ``WindField`` whose ``sample`` adds the wakes' means) with the design's
        # tip-speed ratios and one calibration bias per sensor
        self._one_measure_kernel = (
            self._fast is not None and wind_field is None and self._tsr_shift is None and self.bias.ndim == 1
        )
        if self._one_measure_kernel:
            table, slope, per_rad, offsets = self.wind.interpolation()
            self._wind_table = (np.stack([table, slope]), per_rad, offsets)
        # the one-kernel measurement's outputs read within the tick, as planes of two blocks (``PLANES``): the blades'
        # wind, torques and pitch errors (3, n, 3), the rotor's wind and τ_r (2, n)
        self._per_blade, self._per_row = np.empty((3, self.n, 3)), np.empty((2, self.n))
        # ``_fast_measure_frame``'s kernel arguments while the faults stay, and ``control``'s (``_measure_arguments``):
        # ``wwcore.kept.Kept`` structs, built by the compiled module (``self._fast.Kept``: no compiler on import)
        self._kept = self._control_kept = None
        self._kept_chunk: tuple | None = None  # the wind chunk they hold
        self._wind_row = -1  # the one-kernel measurement's row of the wind chunk (``_wind_sample``)
        self._inputs_ready = False  # ``control`` wrote the shared step's inputs (``advance``)
        self._next_x: np.ndarray | None = None  # and with one row the next state
        # one row's shared step x' = z @ shared inside that kernel call, where its reproduction of numpy's BLAS product
        # (``wwcore.blas_fast.vector_matrix``) is this machine's; else numpy's product in ``advance``
        self._step_product = (
            self.n == 1 and self._fast is not None and self._fast.vector_matrix_is_numpys(N_STATES + 5, N_STATES)
        )
        # the controller's law and the shared step's inputs in one kernel call (``control``), where the controller
        # is the benchmark's own (a farm's replaces it)
        self._fused_control = self._fast is not None

    # -- set-up -----------------------------------------------------------------------------------------------
    def _trim(self, wind0: float, power_reference: float) -> None:
        """Start every row at its own plant's equilibrium under the (design) controller in the initial wind."""
        m = self.mismatch
        if m.aero_nominal:
            groups = [(None, np.arange(self.n))]
        else:
            keys, which = np.unique(np.column_stack([m.aero_factor, m.tsr_shift]), axis=0, return_inverse=True)
            groups = [(PlantAero(*key), np.flatnonzero(which.ravel() == i)) for i, key in enumerate(keys)]
        zone, pitch, tau_g = np.zeros(self.n, dtype=np.int8), np.zeros(self.n), np.zeros(self.n)
        for aero_plant, rows in groups:
            op = trim(self.p, wind0, power_reference, aero_plant)
            self.x[rows, OMEGA_R], self.x[rows, OMEGA_G], self.x[rows, THETA], self.x[rows, TAU_G] = (
                op.omega_r,
                op.omega_g,
                op.theta,
                op.tau_g,
            )
            self.x[rows[:, None], PITCH] = op.pitch
            zone[rows], pitch[rows], tau_g[rows] = op.zone, op.pitch, op.tau_g
        self.x[:, THETA] /= m.stiffness_factor  # the shaft's steady twist under the plant's own stiffness
        self.controller.initialise(zone, pitch, tau_g)

    def inject(self, fault: FaultSpec) -> None:
        """Schedule a fault (from the scenario, or at run time from the API: start ≥ now)."""
        rows = np.flatnonzero((self.turbine_of_row == fault.turbine) & ~self.twin_of_row)
        start = round(fault.start_s / self.dt)
        end = None if fault.end_s is None else round(fault.end_s / self.dt)
        self.schedule.append(ScheduledFault(fault, rows, max(start, self.k), end))
        self._next_change = self.k

    def clear(self, label: str) -> bool:
        """End a fault now. Returns False when no active or pending fault has that label."""
        for sched in self.schedule:
            if sched.spec.label == label and (sched.end_tick is None or sched.end_tick > self.k):
                sched.end_tick = max(self.k, sched.start_tick)
                self._next_change = self.k
                return True
        return False

    def end_all_faults(self) -> None:
        """End every active fault now and drop the pending ones: from this tick on the batch runs fault-free (a
        fault-free twin that branches off a run, ``windwarden.evaluation.turbine``)."""
        self.schedule = [s for s in self.schedule if s.start_tick < self.k]
        for sched in self.schedule:
            if sched.end_tick is None or sched.end_tick > self.k:
                sched.end_tick = self.k
        self._next_change = self.k

    # -- the step contract --------------------------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self.k * self.dt

    def measure(self) -> TurbineFrame:
        """Sensor readings y_k with noise and sensor faults (PARAMETERS.md a.3)."""
        if self.k >= self._next_change:  # ``_update_faults``' own first test, without its call on a quiet tick
            self._update_faults()
        x = self.x
        if self._one_measure_kernel:
            return self._fast_measure_frame(x)
        ws = self.wind.sample(self.k, x[:, AZIMUTH])
        self._wind_sample = ws
        pitch = x[:, PITCH]
        f = self.faults
        fast = self._fast
        if fast is not None and self._tsr_shift is None:
            gain = self.dynamics.blade_gain * f.aero_factor
            self.blade_torque, self.tau_aero = fast.blade_torques(
                x[:, OMEGA_R], pitch + f.pitch_offset, ws.blades, gain, self.p.radius
            )
            if self.bias.ndim == 1:
                return self._fast_frame(fast, x, ws, pitch)
        else:
            self.blade_torque = torque = self.dynamics.blade_torques(
                x[:, OMEGA_R], pitch + f.pitch_offset, ws.blades, f.aero_factor, self._tsr_shift
            )
            self.tau_aero = (torque[:, 0] + torque[:, 1]) + torque[:, 2]  # Σ_i τ_r,i, in sum(axis=1)'s order
        # [ω_r, ω_g, v_hub, β_1..3, τ_g, P_g] (``_QUANTITIES``) written into a reused buffer: cheaper than stacking
        quantities = self._quantities
        quantities[:, :2] = x[:, OMEGA_R : OMEGA_G + 1]
        quantities[:, 2] = ws.hub
        quantities[:, 3:6] = pitch
        quantities[:, 6] = x[:, TAU_G]
        quantities[:, 7] = self.power_output(x)
        noise = self._next_noise()  # already σ-scaled
        if f.sensor_faults_active:
            y = (quantities[:, _PICK] + self.bias + noise * f.noise_scale) * f.gain + f.offset
            if f.drift_active:
                y += f.drift_rate * (self.t - f.drift_start)
            y = np.where(f.fixed, f.fixed_value, y)
            y = np.where(f.stuck, f.stuck_value, y)
        else:
            y = quantities[:, _PICK] + (noise + self.bias)
        self.last_reading = y
        # Pitch-sensor errors reach the true pitch (PARAMETERS.md a.2): β_i,f = ½(β_i,m1 + β_i,m2) − β_i is added
        # to actuator i's reference, as the benchmark's Blade & Pitch "Add" blocks do (signs ++). An inner loop
        # that drove the measured mean to β_ref would subtract it instead; we follow the implementation, with
        # which every published FDI result on this benchmark was obtained (docs/turbine.md).
        beta_m = y[:, _BETA_M12]
        self._pitch_error = 0.5 * (beta_m[:, :3] + beta_m[:, 3:]) - pitch
        return self._frame(y, self.k)

    def _frame(self, y: np.ndarray, k: int) -> TurbineFrame:
        """Tick ``k``'s frame of the readings ``y``, with copies of the controller's outputs of tick k−1."""
        c = self.controller
        return TurbineFrame(k, k * self.dt, y, c.tau_g_ref.copy(), c.beta_ref.copy(), c.power_ref.copy(), c.zone.copy())

    def _fast_measure_frame(self, x: np.ndarray) -> TurbineFrame:
        """``measure`` with the plant's own ``WindField`` by one kernel (``plant_sim.turbine.fast.measure``: the wind
        sample, the blade torques and the readings, the same operations as ``sample``, ``blade_torques`` and
        ``_fast_frame``), then with a sensor fault active ``faulty_readings`` in the readings' place. The kernel reads
        the tick's row of the wind chunk and column of the noise block itself; its arguments are kept between ticks
        (``_measure_arguments``); the readings ``y`` are new every tick (the frame hands them on)."""
        wind, k = self.wind, self.k
        j = wind.advance(k)
        i = k % self.noise_chunk
        if i == 0 or not self._noise_drawn:
            self._draw_noise()
        kept = self._kept
        if kept is None or self._kept_chunk is not wind.chunk:
            kept = self._measure_arguments()
        y = np.empty((self.n, len(SENSORS)))
        fast = self._fast
        fast.measure_kept(x, j, i, kept, y)
        self._sample, self._wind_row = None, j  # ``_wind_sample`` built when asked
        if self.faults.sensor_faults_active:
            return self._fast_faulty_frame(fast, x, self._tick_noise, y)
        self.last_reading = y
        return self._frame(y, k)

    def _measure_arguments(self):
        """``_fast_measure_frame``'s kernel arguments that stay from tick to tick until the faults change
        (``_update_faults`` drops them) or the wind's next chunk starts: the chunk, the fault factors, the constants,
        the noise block, and the outputs read within the tick (the blades' and rotor's wind and the torques: the
        evaluation and the twins copy what they keep), as one ``wwcore.kept.Kept``; with them, for the benchmark's
        controller, ``control``'s kept arguments as another (``fast.control_inputs_kept``: the readings' columns, the
        controller's arrays, written in place, and constants, the two output blocks, Δτ, the step's z and matrix)."""
        f, per_blade, per_row = self.faults, self._per_blade, self._per_row
        self.blade_torque, self._pitch_error, self.tau_aero = per_blade[1], per_blade[2], per_row[1]
        self._kept_chunk = chunk = self.wind.chunk
        self._kept = self._fast.Kept((
            (*self._wind_table, *chunk[:3]),
            (self._fast.M_T, self.dynamics.blade_gain, f.aero_factor, f.pitch_offset, self.p.radius),
            (self.p.eta_gc, f.power_factor, _MEASURE_COLUMNS, self._draws, self._tick_noise, self.bias),
            (per_blade, per_row, self._quantities),
        ))  # fmt: skip
        c = self.controller
        if type(c) is BenchmarkController:  # the blocks, not their planes (``wwcore.planes``)
            law = (c.zone, c.integrator, c.beta_ref, c.tau_g_ref, c._constants)
            step = (per_blade, per_row, f.torque_offset, self.discrete.inputs, self.discrete.shared)
            self._control_kept = self._fast.Kept((_CONTROL_COLUMNS, *law, *step))
        return self._kept

    @property
    def _wind_sample(self) -> WindSample:
        """The current tick's wind (``WindSample``); the one-kernel measurement's built from its outputs when asked."""
        if self._sample is None and self._wind_row >= 0:
            _, _, hub, mean = self._kept_chunk
            j = self._wind_row
            self._sample = WindSample(blades=self._per_blade[0], hub=hub[j], rotor=self._per_row[0], mean=mean[j])
        return self._sample

    @_wind_sample.setter
    def _wind_sample(self, sample: WindSample) -> None:
        self._sample, self._wind_row = sample, -1

    def _fast_frame(self, fast, x: np.ndarray, ws, pitch: np.ndarray) -> TurbineFrame:
        """``measure``'s readings, by ``plant_sim.turbine.fast``: ``readings``, then with a sensor fault active
        ``faulty_readings`` in their place (the same operations as the numpy code's two branches)."""
        y = np.empty((self.n, len(SENSORS)))
        self._pitch_error = np.empty((self.n, 3))
        power_gain = self.p.eta_gc * self.faults.power_factor
        noise = self._next_noise()
        fast.readings(
            x, ws.hub, power_gain, _PICK, noise, self.bias, _BETA_M1, _BETA_M2, self._quantities, y, self._pitch_error
        )
        return self._fast_faulty_frame(fast, x, noise, y)

    def _fast_faulty_frame(self, fast, x: np.ndarray, noise: np.ndarray, y: np.ndarray) -> TurbineFrame:
        """The frame of the healthy readings ``y``, with a sensor fault active ``faulty_readings`` in their place
        first (in place, from the tick's quantities and ``noise``)."""
        f = self.faults
        if f.sensor_faults_active:
            faults = (f.noise_scale, f.gain, f.offset, f.drift_rate, f.drift_start, f.fixed, f.fixed_value)
            faults += (f.stuck, f.stuck_value)
            sensors = (self._quantities, _PICK, noise, self.bias, _BETA_M1, _BETA_M2)
            fast.faulty_readings(*sensors, x, faults, self.t, f.drift_active, y, self._pitch_error)
        self.last_reading = y
        return self._frame(y, self.k)

    def control(self, refs: TurbineRefs | None) -> None:
        y, c = self.last_reading, self.controller
        if self._fused_control and type(c) is BenchmarkController:
            # the law and, where ``advance`` takes the shared step, that step's inputs z (with one row its product
            # too) in one kernel call: x, τ_r, the faults and the pitch-sensor errors stay as they are until ``advance``
            shared = self.discrete.shared
            fill = shared is not None and not self._adjusted()
            if self._control_kept is not None:  # the one-kernel measurement's kept arguments (``_measure_arguments``)
                self._next_x = np.empty((1, N_STATES)) if fill and self._step_product else None
                c.step_readings_kept(self.k, y, refs, self._control_kept, fill, self.x, self._next_x)
                self._inputs_ready = fill
                return
            inputs = (fill, self.x, self.tau_aero, self.faults.torque_offset, self._pitch_error, self.discrete.inputs)
            product = (shared, np.empty((1, N_STATES))) if fill and self._step_product else None
            self._next_x = None if product is None else product[1]
            c.step_readings(self.k, y, _CONTROL_COLUMNS, refs, inputs, product)
            self._inputs_ready = fill
            return
        c.step(self.k, y[:, _OMEGA_G_M1], y[:, _P_G_M], refs)

    def advance(self) -> None:
        """Exact step from tick k to k+1 with controller outputs, wind and aerodynamic torque held."""
        if self._inputs_ready:  # ``control`` wrote the shared step's inputs (every row alike, nothing else in them)
            self._inputs_ready, next_x = False, self._next_x
            self.x = self.discrete.inputs @ self.discrete.shared if next_x is None else next_x
            self.k += 1
            return
        c, f, x = self.controller, self.faults, self.x
        shared = self.discrete.shared
        if self._fast is not None and shared is not None and not self._adjusted():
            # every row alike and nothing but the commands and the pitch-sensor errors in the inputs
            z = self.discrete.inputs
            self._fast.step_inputs(x, self.tau_aero, c.tau_g_ref, f.torque_offset, c.beta_ref, self._pitch_error, z)
            self.x = z @ shared
            self.k += 1
            return
        pitch_ref = c.beta_ref[:, None] + self._pitch_error
        if f.command_offset_active:
            pitch_ref = pitch_ref + f.pitch_command_offset
        if c.pitch_trim is not None:  # a farm supervisor's per-blade correction (``plant_sim.farm.controller``)
            pitch_ref = pitch_ref + c.pitch_trim
        tau_r, tau_ext = self.tau_aero, None
        if f.mesh_active or self._error_active:
            # Drive-train wear (farm fault 3): the shaft twists by θ_Δ − e(ψ), e = e_0 cos 3ψ, so the error acts as
            # an internal torque pair T = K_dt e(ψ) (N m, low-speed shaft): +T on the rotor, −η_dt T/N_g on the
            # generator, held over the step like τ_r. T is taken at the step's mid-azimuth: K_dt e_0 is ≈ 13 MN m,
            # and a pair held from the step's start lags e by Δt/2, which puts a spurious K_dt e_0 3ω_r Δt/2
            # (0.35 MN m at rated speed) into the shaft torque. e_0 develops through two 0.25 s lags: a step, or a
            # single lag's kink, rings the 4.5 Hz torsion mode (docs/farm.md, D-F3).
            gain = self.dt / ERROR_ONSET_S
            self._error_stage += (f.transmission_error - self._error_stage) * gain
            self._error_level += (self._error_stage - self._error_level) * gain
            residue = np.abs(self._error_level) + np.abs(self._error_stage)
            self._error_active = f.mesh_active or bool(np.any(residue > 1e-9))
            mid_step = x[:, AZIMUTH] + (0.5 * self.dt) * x[:, OMEGA_R]
            pair = (self.p.K_dt * f.stiffness_factor) * self._error_level * np.cos(3.0 * mid_step)
            tau_r, tau_ext = tau_r + pair, -f.eta_dt * pair / self.p.N_g
        self.x = self.discrete.step(x, tau_r, c.tau_g_ref + f.torque_offset, pitch_ref, tau_ext)
        self.k += 1

    def _adjusted(self) -> bool:
        """Whether the step's inputs get more than the controller's commands and the pitch-sensor errors."""
        f = self.faults
        return f.command_offset_active or self.controller.pitch_trim is not None or f.mesh_active or self._error_active

    def truth(self) -> dict[str, np.ndarray]:
        """Ground truth for scoring and display only; the supervisor never reads it."""
        x, ws = self.x, self._wind_sample
        return {
            "omega_r": x[:, OMEGA_R].copy(),
            "omega_g": x[:, OMEGA_G].copy(),
            "theta": x[:, THETA].copy(),
            "tau_g": x[:, TAU_G].copy(),
            "pitch": x[:, PITCH].copy(),
            "power": self.power_output(x),
            "tau_aero": self.tau_aero.copy(),
            "wind_rotor": ws.rotor.copy(),
            "wind_hub": ws.hub.copy(),
            "wind_mean": ws.mean.copy(),
            "zone": self.controller.zone.copy(),
        }

    def true_rotor_wind(self) -> np.ndarray:
        """The true rotor-effective wind of the current tick (m/s, no copy): for scoring only."""
        return self._wind_sample.rotor

    def drain_events(self) -> list[Event]:
        events, self._events = self._events, []
        return events

    # -- internals ----------------------------------------------------------------------------------------------
    def power_output(self, x: np.ndarray | None = None) -> np.ndarray:
        """Electrical power output P_g = η_gc ω_g τ_g, W, times the farm debris fault's output factor (truth)."""
        x = self.x if x is None else x
        return (self.p.eta_gc * self.faults.power_factor) * x[:, OMEGA_G] * x[:, TAU_G]

    def shaft_torque(self) -> np.ndarray:
        """Torque in the low-speed shaft, K_dt (θ_Δ − e(ψ)) + B_dt (ω_r − ω_g/N_g), N m (truth, for damage)."""
        x, f, p = self.x, self.faults, self.p
        twist = x[:, THETA] - self._error_level * np.cos(3.0 * x[:, AZIMUTH]) if self._error_active else x[:, THETA]
        stiffness = p.K_dt * f.stiffness_factor
        return stiffness * twist + (p.B_dt * f.damping_factor) * (x[:, OMEGA_R] - x[:, OMEGA_G] / p.N_g)

    def _draw_noise(self) -> None:
        """The noise block of the ticks from this one: each row with its own stream draws (noise_chunk, N_SENSORS)
        numbers, as one standard_normal call of that size would, σ-scaled. Twin rows (second half) share their run's
        streams, hence its numbers."""
        if self._random is not None:  # numpy's numbers and σ-scaling in one compiled pass per row, the same values
            sigma = self.sigma
            for i, rng in enumerate(self._noise_rngs[: self._noise_rows]):
                self._random.scaled_normals(rng, self._draws[i], sigma if sigma.ndim == 1 else sigma[i, 0])
            self._noise_drawn = True
            return
        for i, rng in enumerate(self._noise_rngs[: self._noise_rows]):
            rng.standard_normal(out=self._draws[i])
        self._draws *= self.sigma
        self._noise_drawn = True

    def _next_noise(self) -> np.ndarray:
        """σ-scaled sensor noise of the current tick (n, N_SENSORS): a view, valid for this tick only."""
        j = self.k % self.noise_chunk
        if j == 0 or not self._noise_drawn:
            self._draw_noise()
        noise = self._draws[:, j]
        if self._noise_rows == self.n:
            return noise
        rows = self._noise_rows
        self._tick_noise[:rows] = noise
        self._tick_noise[rows:] = noise
        return self._tick_noise

    def _update_faults(self) -> None:
        k, dt = self.k, self.dt
        if k < self._next_change:
            return
        self._next_change = min((s.next_change(k, dt) for s in self.schedule), default=np.iinfo(np.int64).max)
        if not any(s.changing(k, dt) for s in self.schedule):
            return
        for sched in self.schedule:
            if k == sched.start_tick and k != sched.end_tick:
                if sched.spec.kind is FaultKind.STUCK:
                    sched.held = self.last_reading[sched.rows, SENSOR_INDEX[sched.spec.target]].copy()
                self._emit(EventType.FAULT_INJECTED, sched)
            elif k == sched.end_tick and k > sched.start_tick:
                self._emit(EventType.FAULT_CLEARED, sched)
        self.faults.reset()
        self._kept = self._control_kept = None  # the fault factors and the step matrix are new arrays
        for sched in self.schedule:
            level = sched.intensity(k, dt)
            if level > 0.0:
                self.faults.apply(sched.spec, sched.rows, level, sched.held)
        self.discrete.update(self.faults)

    def _emit(self, kind: EventType, sched: ScheduledFault) -> None:
        spec = sched.spec
        detail = {"label": spec.label, "kind": spec.kind.value}
        if spec.value is not None:
            detail["value"] = spec.value
        for row in sched.rows:
            self._events.append(
                Event(
                    t=self.t,
                    type=kind,
                    turbine=int(self.turbine_of_row[row]),
                    target=spec.target,
                    run=int(self.run_of_row[row]),
                    detail=dict(detail),
                )
            )
