"""The farm following the step contract of ``wwcore.stepping``, batched over Monte Carlo runs.

Rows are turbines of farms, farm-major (``wwcore.farm_frames``): the turbines are one ``TurbineBatch`` with
``turbines = 1 … N`` (N = 9 on the paper's 3 × 3; any layout's with FLORIS wakes, ``plant_sim.farm.wakes``), each
with its own controller, sensor noise and turbulence streams (``row_streams``), driven by a ``FarmWindField`` (met
mast, delays, wakes: the row model or FLORIS's tables, built here at start). With ``fault_free_twins`` every run has
a second farm with the same wind and noise streams and no faults, for scoring what the faults cost (damage numbers).

Tick k (100 Hz) of the farm:

1. ``measure()``: at the start of each 10 Hz block (k mod 10 = 0) the wind field takes the turbines' aerodynamic
   power and moves the wakes on; the turbines measure; their readings are summed into the block's SCADA means.
   The last tick of a block (k mod 10 = 9) is a *farm sample*: SCADA means, a new met-mast reading (true mast wind
   + noise; the vane's direction + noise, from a stream of its own) and the demand go out with the frame.
2. ``control(refs)``: a newer ``FarmRefs`` sets each turbine's power reference (followed at the turbine's ramp
   rate); the turbine controllers run.
3. ``advance()``: the turbines integrate to k + 1.

``run_sample(refs)`` makes these calls for the ticks up to the end of the farm sample, the references unchanged
(the farm supervisor answers samples only): the farm evaluation's loop. With the compiled backend a sample of
common ticks is one call of ``plant_sim.farm.fast.sub_steps``, with the same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import signal

from plant_sim.farm.controller import (
    EXTRA_MAX_AGE_S,
    FarmTurbineController,
)
from plant_sim.farm.direction import DirectionSeries
from plant_sim.farm.sample_kernel import SampleArguments, run_compiled_sample
from plant_sim.farm.wakes import TableWakes, plant_wake_tables
from plant_sim.farm.wind import HISTORY_S, MIN_MEAN_WIND, FarmWakes, FarmWindField, MastSeries, RowWakes
from plant_sim.turbine import TurbineBatch
from plant_sim.turbine.dynamics import N_STATES, OMEGA_G, OMEGA_R, PITCH, TAU_G, THETA
from plant_sim.turbine.plant import row_streams
from plant_sim.turbine.trim import PlantAero, trim
from wwcore.channels import N_SENSORS
from wwcore.events import Event
from wwcore.farm_frames import FarmFrame, FarmRefs
from wwcore.scenario.farm import FARM_DT_S, FarmPlant
from wwcore.scenario.faults import FaultSpec
from wwcore.scenario.mismatch import Mismatch
from wwcore.scenario.turbine import TurbinePlant
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_frames import TurbineFrame
from wwcore.turbine_params import BENCHMARK, TurbineParams

MAST_TURBINE = 0  # turbine number of the met mast's random streams (row_streams(seed, run, 0))
VANE_STREAM = 2  # the vane's noise: child 2 of the mast's SeedSequence (row_streams takes children 0 and 1)
VEER_STREAM = 3  # the random veer of the wind direction: child 3
ROW_STREAM_BASE = 100  # row i's shared turbulence: row_streams(seed, run, max(100, N + 1) + i) (row_coherence > 0)
TRIM_WINDS = np.arange(2.0, 35.01, 0.25)  # m/s, grid of the initial operating points


def mast_child_stream(seed: int, run: int, child: int) -> np.random.Generator:
    """Child ``child`` of the mast's SeedSequence for one run (a SeedSequence's children do not depend on how many
    are spawned, so each is independent of every stream ``row_streams`` gives and of the other children)."""
    children = np.random.SeedSequence(seed, spawn_key=(run, MAST_TURBINE)).spawn(child + 1)
    return np.random.default_rng(children[child])


def vane_stream(seed: int, run: int) -> np.random.Generator:
    """The met-mast vane's noise stream of one run: adding the vane changed no other draw."""
    return mast_child_stream(seed, run, VANE_STREAM)


def veer_stream(seed: int, run: int) -> np.random.Generator:
    """The random veer's stream of one run (``plant_sim.farm.direction``): switching the veer on changes no other
    draw."""
    return mast_child_stream(seed, run, VEER_STREAM)


def demand_series(
    plant: FarmPlant, params: TurbineParams, mast: MastSeries, duration_s: float, wakes: FarmWakes
) -> np.ndarray:
    """P_ref,farm (W) of each run at every farm sample j (t = j·FARM_DT_S), shape (runs, samples)."""
    n = int(np.ceil(duration_s / FARM_DT_S)) + 2
    t = np.arange(n) * FARM_DT_S
    spec = plant.demand
    if spec.mode == "profile":
        times, mw = zip(*spec.points, strict=True)
        return np.broadcast_to(np.interp(t, times, mw) * 1e6, (mast.v.shape[0], n)).copy()
    # Delta control: fraction × the farm's available power, from the free stream each row sees (the mast wind
    # delayed by d_j/v̄, eq. (3)) averaged over ``averaging_s`` (first order) and ``wakes``' static model; set every
    # ``update_s`` and held. Computed from the true wind: the demand is an exogenous signal, "below the available
    # power" by construction up to the turbines' own turbulence.
    rows_free = wakes.free_stream_series(n)  # a moving direction: along it (plant_sim.farm.direction)
    if rows_free is None:
        runs = np.arange(mast.v.shape[0])[:, None, None]
        d = wakes.mast_distances  # (rows,) or (turbines,): where the free stream is delayed to
        vbar = np.maximum(mast.vbar[:, mast.offset : mast.offset + n], MIN_MEAN_WIND)  # (runs, n)
        delays = np.minimum(d[None, None, :] / vbar[:, :, None], HISTORY_S)  # (runs, n, rows)
        rows_free = mast.at(np.broadcast_to(runs, delays.shape), t[None, :, None] - delays)
    a = np.exp(-FARM_DT_S / spec.averaging_s)
    avg, _ = signal.lfilter([1.0 - a], [1.0, -a], rows_free, axis=1, zi=rows_free[:, :1, :] * a)
    held = np.minimum(np.rint(np.floor(t / spec.update_s) * spec.update_s / FARM_DT_S).astype(int), n - 1)
    return spec.fraction * wakes.available_power(params, avg, held)


@dataclass
class FarmBlock:
    """The ticks one ``FarmBatch.run_sample`` call ran, from ``first_tick`` on: the last tick's frame (the farm
    sample's when the block reached it) and each tick's truth the evaluation reads, taken at the tick's state."""

    first_tick: int
    frame: FarmFrame
    states: np.ndarray | None  # (ticks, n, N_STATES) each turbine's state x, when asked for
    power: np.ndarray  # (ticks, n) W, each turbine's electrical power (``FarmBatch.power_output``)
    shaft_torque: np.ndarray | None  # (ticks, n) N m (``FarmBatch.shaft_torque``), when asked for


class FarmBatch:
    """``runs`` Monte Carlo runs of the farm (and their fault-free twins), one 100 Hz tick per step call.

    ``mismatch`` (a scenario's ``[mismatch]`` section) gives each turbine of each run its own plant
    (``plant_sim.turbine.mismatch``): drawn per turbine and run from the section's spread, or set per turbine. The
    wakes see each rotor's own air density; the demand's available-power estimate stays the design model's, as a
    grid operator's would. ``backend`` (``wwcore.backend``) is the turbines' (``TurbineBatch``).
    """

    def __init__(
        self,
        plant: FarmPlant,
        wind: WindSpec,
        faults: Sequence[FaultSpec],
        *,
        seed: int,
        duration_s: float,
        runs: Sequence[int] = (0,),
        params: TurbineParams = BENCHMARK,
        fault_free_twins: bool = False,
        mismatch: Mismatch | None = None,
        wake_cache_dir: Path | str | None = None,
        backend: str | None = None,
    ):
        self.spec = plant
        self.p = params
        self.dt = params.dt
        self.k = 0
        self.runs = list(runs)
        copies = 2 if fault_free_twins else 1
        self.farms = copies * len(self.runs)
        self.run_of_farm = np.tile(np.arange(len(self.runs)), copies)  # index into ``runs``
        self.twin_of_farm = np.repeat(np.arange(copies) == 1, len(self.runs))
        self.ticks_per_sample = round(FARM_DT_S / self.dt)
        mast_streams = [row_streams(seed, int(r), MAST_TURBINE) for r in self.runs]
        self.mast = MastSeries(plant, wind, [w for w, _ in mast_streams], duration_s)
        self._mast_noise = [noise for _, noise in mast_streams]
        self._mast_noise_chunk = np.empty((len(self.runs), 0))
        self._vane_noise = [vane_stream(seed, int(r)) for r in self.runs]
        self._vane_noise_chunk = np.empty((len(self.runs), 0))
        veer = [veer_stream(seed, int(r)) for r in self.runs] if plant.veer_sigma_deg > 0.0 else None
        self.direction = DirectionSeries(plant, veer, len(self.runs), duration_s)  # θ(t) of each run, deg
        self.n_turbines = n_turbines = plant.n_turbines
        self.wakes: FarmWakes
        if plant.wake_model == "rows":
            self.wakes = RowWakes(plant, params, self.mast, self.run_of_farm)
        else:
            tables = plant_wake_tables(plant, wind, params, wake_cache_dir) if plant.wakes else None
            self.wakes = TableWakes(plant, params, tables, self.mast, self.run_of_farm, self.direction, backend)
        self.demand = demand_series(plant, params, self.mast, duration_s, self.wakes)  # (runs, samples) W
        wind_rngs = [
            row_streams(seed, int(r), t)[0] for _ in range(copies) for r in self.runs for t in range(1, n_turbines + 1)
        ]
        n_rows = len(plant.rows())
        row_base = max(ROW_STREAM_BASE, n_turbines + 1)  # row streams are numbered after the turbines'
        row_rngs = [
            row_streams(seed, int(r), row_base + i)[0] for _ in range(copies) for r in self.runs for i in range(n_rows)
        ]
        self.field = FarmWindField(
            plant,
            wind,
            params,
            wind_rngs,
            self.mast,
            self.run_of_farm,
            self.dt,
            row_rngs=row_rngs,
            wakes=self.wakes,
            backend=backend,
        )
        turbine_spec = TurbinePlant(noise_convention=plant.noise_convention, power_reference_w=params.rated_power)
        self.turbines = TurbineBatch(
            turbine_spec,
            wind,
            faults,
            seed=seed,
            runs=self.runs,
            turbines=range(1, n_turbines + 1),
            params=params,
            wind_field=self.field,
            fault_free_twins=fault_free_twins,
            mismatch=mismatch,
            backend=backend,
        )
        if mismatch is not None:
            self.field.set_air_density(params.rho * self.turbines.mismatch.density_ratio)
        self.n = self.turbines.n
        self.controller = FarmTurbineController(
            params, self.n, params.rated_power, plant.cancel_3p_in_hold, backend=self.turbines.backend
        )
        self.turbines.controller = self.controller
        self._trim(self.field.turbine_wind.reshape(-1))
        self._scada_sum = np.zeros((self.n, N_SENSORS))
        self._power_ref_sum = np.zeros(self.n)
        self.scada = np.zeros((self.n, N_SENSORS))
        self.power_ref_used = np.full(self.n, params.rated_power)
        self.mast_reading = self.mast.v[:, self.mast.offset].copy()
        self.vane_reading = np.mod(self.direction.at(np.arange(len(self.runs)), 0), 360.0)
        self._refs_tick = -1
        self._opened = -1  # the tick whose farm sample was last opened (``_open_sample``)
        self._sample_arguments: SampleArguments | None = None  # ``_sub_steps``'s, while the fault factors stay

    # -- set-up -----------------------------------------------------------------------------------------------
    def _trim(self, wind0: np.ndarray) -> None:
        """Start every turbine at the steady operating point of its row's initial mean wind, at rated reference."""
        m = self.turbines.mismatch
        if not m.aero_nominal:
            self._trim_each(wind0)
            return
        points = [trim(self.p, float(v)) for v in TRIM_WINDS]
        x = self.turbines.x
        table = {name: np.array([getattr(op, name) for op in points]) for name in ("omega_r", "theta", "tau_g")}
        x[:, OMEGA_R] = np.interp(wind0, TRIM_WINDS, table["omega_r"])
        x[:, OMEGA_G] = x[:, OMEGA_R] * self.p.N_g
        x[:, THETA] = np.interp(wind0, TRIM_WINDS, table["theta"]) / m.stiffness_factor
        x[:, TAU_G] = np.interp(wind0, TRIM_WINDS, table["tau_g"])
        pitch = np.interp(wind0, TRIM_WINDS, [op.pitch for op in points])
        zone = np.interp(wind0, TRIM_WINDS, [op.zone for op in points]) >= 0.5
        x[:, PITCH] = pitch[:, None]
        x[:, PITCH + 1] = 0.0
        self.controller.initialise(zone.astype(np.int8), pitch, x[:, TAU_G].copy())

    def _trim_each(self, wind0: np.ndarray) -> None:
        """``_trim`` for turbines whose aerodynamics differ from the design's: each its own equilibrium."""
        m, x = self.turbines.mismatch, self.turbines.x
        keys = np.column_stack([wind0, m.aero_factor, m.tsr_shift])
        distinct, which = np.unique(keys, axis=0, return_inverse=True)
        points = [trim(self.p, float(v), None, PlantAero(float(f), float(s))) for v, f, s in distinct]
        which = which.ravel()
        for name, col in (("omega_r", OMEGA_R), ("theta", THETA), ("tau_g", TAU_G)):
            x[:, col] = np.array([getattr(op, name) for op in points])[which]
        x[:, OMEGA_G] = x[:, OMEGA_R] * self.p.N_g
        x[:, THETA] /= m.stiffness_factor
        pitch = np.array([op.pitch for op in points])[which]
        x[:, PITCH] = pitch[:, None]
        x[:, PITCH + 1] = 0.0
        zone = np.array([op.zone for op in points], dtype=np.int8)[which]
        self.controller.initialise(zone, pitch, x[:, TAU_G].copy())

    def row_of(self, farm: int, turbine: int) -> int:
        return farm * self.n_turbines + turbine - 1

    @property
    def run_of_row(self) -> np.ndarray:
        return self.turbines.run_of_row

    @property
    def turbine_of_row(self) -> np.ndarray:
        return self.turbines.turbine_of_row

    @property
    def twin_of_row(self) -> np.ndarray:
        return self.turbines.twin_of_row

    def inject(self, fault: FaultSpec) -> None:
        self.turbines.inject(fault)

    def clear(self, label: str) -> bool:
        return self.turbines.clear(label)

    # -- the step contract ------------------------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self.k * self.dt

    def measure(self) -> FarmFrame:
        k = self.k
        tb = self.turbines
        if k % self.ticks_per_sample == 0 and self._opened != k:
            self._open_sample()
        frame = tb.measure()
        self._scada_sum += frame.sensors
        self._power_ref_sum += frame.power_ref
        return self._farm_frame(k, frame)

    def _open_sample(self) -> None:
        """The first tick of a farm sample: the wind field takes the turbines' operating points and moves the wakes
        on; the block's sums start again."""
        k, tb = self.k, self.turbines
        pitch = tb.x[:, PITCH]
        collective = np.add.reduce(pitch, axis=1) / pitch.shape[1]  # ``pitch.mean(axis=1)``'s sum and division
        self.field.update(k // self.ticks_per_sample, tb.tau_aero * tb.x[:, OMEGA_R], tb.x[:, OMEGA_R], collective)
        self._scada_sum[:] = 0.0
        self._power_ref_sum[:] = 0.0
        self._opened = k

    def _farm_frame(self, k: int, frame: TurbineFrame) -> FarmFrame:
        """Tick k's frame around the turbines' ``frame``; on the last tick of a block the farm sample closes."""
        s = self.ticks_per_sample
        sample = k % s == s - 1
        if sample:
            j = k // s + 1  # the sample closes at t = (k + 1)·dt = j·FARM_DT_S
            self.scada = self._scada_sum * (1.0 / s)
            self.power_ref_used = self._power_ref_sum * (1.0 / s)
            self.mast_reading = self.mast.v[:, self.mast.offset + j] + self.spec.mast_noise_mps * self._mast_noise_now()
            direction = self.direction.deg[:, self.direction.offset + j]  # θ(t), deg (plant_sim.farm.direction)
            vane = direction + self.spec.mast_direction_noise_deg * self._vane_noise_now()
            self.vane_reading = np.mod(vane, 360.0)
        return FarmFrame(
            k=k,
            t=k * self.dt,
            turbines=frame,
            sample=sample,
            scada=self.scada,
            power_ref_used=self.power_ref_used,
            mast=self.mast_reading[self.run_of_farm],
            demand=self.demand[self.run_of_farm, min((k + 1) // s, self.demand.shape[1] - 1)],
            mast_direction=self.vane_reading[self.run_of_farm],
        )

    def control(self, refs: FarmRefs | None) -> None:
        self._take(refs)
        self.turbines.control(None)

    def _take(self, refs: FarmRefs | None) -> None:
        """Newer references than the last ones taken set the turbine controllers' (``set_reference``)."""
        if refs is not None and refs.source_tick != self._refs_tick:
            self._refs_tick = refs.source_tick
            ripple = None
            if refs.ripple_power is not None:  # the phasor's time is the farm sample's: tick source_tick + 1
                ripple = (refs.ripple_power, refs.ripple_rate, (refs.source_tick + 1) * self.dt)
            self.controller.set_reference(
                refs.power_ref, refs.hold_torque, refs.held_torque, refs.pitch_trim, ripple, refs.cancel_3p
            )

    def advance(self) -> None:
        self.turbines.advance()
        self.k = self.turbines.k

    # -- a farm sample's ticks at once ------------------------------------------------------------------------
    def run_sample(
        self, refs: FarmRefs | None, ticks: int | None = None, shaft_torque: bool = False, states: bool = True
    ) -> FarmBlock:
        """``measure`` → ``control(refs)`` → ``advance`` for every tick from k to the end of its farm sample (at most
        ``ticks``): the step contract's loop for a supervisor that answers farm samples only (``FarmSupervisor``
        returns the same references in between), which is then given the returned block's ``frame``. The block
        carries each tick's states unless ``states`` is false (the evaluation reads the power and shaft torque
        only: the (ticks, n, N_STATES) array and its stores are then not made).

        With the compiled backend (``wwcore.backend``) a whole sample is one ``plant_sim.farm.fast.sub_steps`` call
        after the wakes' step when nothing but the common tick happens in it (no fault starts,
        ends or acts on the sensors, the step matrix is every turbine's, no transmission error, hold, 3P
        cancellation or power phasor, no new turbulence or noise block), with the same numbers; otherwise the calls
        again."""
        k0, s = self.k, self.ticks_per_sample
        count = s - k0 % s if ticks is None else min(ticks, s - k0 % s)
        if count < 1:
            raise ValueError(f"run_sample needs at least one tick, got ticks = {ticks}")
        kept = np.empty((count, self.n, N_STATES)) if states else None
        power = np.empty((count, self.n))
        shaft = np.empty((count, self.n)) if shaft_torque else None
        if count == s and self.field._farm_fast is not None:
            # a whole sample: the wakes' step and the references first (neither changes what the turbines measure
            # on the sample's first tick), then the ticks at once if they are common ones
            self._open_sample()
            self._take(refs)
            if self._sub_steps_apply(count):
                frame = self._sub_steps(kept, power, shaft)
                return FarmBlock(first_tick=k0, frame=frame, states=kept, power=power, shaft_torque=shaft)
        for i in range(count):
            frame = self._tick(refs, kept, power, shaft, i)
        return FarmBlock(first_tick=k0, frame=frame, states=kept, power=power, shaft_torque=shaft)

    def _tick(
        self, refs: FarmRefs | None, states: np.ndarray | None, power: np.ndarray, shaft: np.ndarray | None, i: int
    ) -> FarmFrame:
        """One tick of the contract, with its state (if asked for) and true power (and shaft torque) into row i of
        the block."""
        frame = self.measure()
        self.control(refs)
        if states is not None:
            states[i] = self.turbines.x
        power[i] = self.power_output()
        if shaft is not None:
            shaft[i] = self.shaft_torque()
        self.advance()
        return frame

    def _sub_steps_apply(self, count: int) -> bool:
        """Whether the next ``count`` ticks (a sample's, opened) are common ticks ``sub_steps`` runs. A sample that
        starts a turbulence chunk or a noise block has it made first, as its first tick would (the turbulence chunk
        in any case: the tick refills only past the chunk's end; the noise block only when the sample is common: the
        tick draws at the block's start)."""
        tb, c, field, f = self.turbines, self.controller, self.field, self.turbines.faults
        k, chunk = self.k, tb.noise_chunk
        if field._farm_fast is not None and field._next_k == k == field._chunk_end:
            field._refill()
        block_start = k % chunk == 0
        common = (
            tb._fast is not None
            and field._farm_fast is not None
            and c._farm_fast is not None
            and tb._tsr_shift is None
            and tb.bias.ndim == 1
            and k + count <= tb._next_change  # no fault starts or ends (``TurbineBatch._update_faults``)
            and not f.sensor_faults_active
            and tb.discrete.shared is not None
            and field._next_k == k
            and field._chunk_start <= k
            and k + count <= field._chunk_end  # the turbulence chunk holds every tick
            and (tb._noise_drawn or block_start)
            and k % chunk + count <= chunk  # so does the noise block
            and c._bp_ready
            and (c._extra is None or (k + count - 0.5) * self.dt - c._extra[2] <= EXTRA_MAX_AGE_S)  # kept throughout
            and not c._handing_over
            and not c.hold.any()
        )
        if common and block_start:
            tb._draw_noise()
        return common

    def _sub_steps(self, states: np.ndarray | None, power: np.ndarray, shaft: np.ndarray | None) -> FarmFrame:
        """``len(power)`` common ticks by ``plant_sim.farm.fast.sub_steps`` (``sample_kernel``), with the arguments
        kept since the last compiled sample while the turbines' fault factors are the same arrays; the last tick's
        frame."""
        kept = self._sample_arguments
        if kept is None or not kept.current(self):
            kept = self._sample_arguments = SampleArguments(self)
        return run_compiled_sample(self, kept, states, power, shaft)

    def truth(self) -> dict[str, np.ndarray]:
        """Ground truth for scoring and display only; the supervisor never reads it."""
        out = self.turbines.truth()
        out["shaft_torque"] = self.turbines.shaft_torque()
        out["row_wind"] = self.field.turbine_wind.reshape(-1)  # the turbine's mean wind (its row's, row model)
        out["free_wind"] = self.field.free_wind.reshape(-1)
        # the direction (deg, 0 … <360) of the air each turbine sees; the mast's θ reaches it with the wind
        out["wind_direction"] = np.mod(self.wakes.turbine_direction, 360.0).reshape(-1)
        out["power_ref"] = self.controller.power_ref.copy()
        return out

    def drain_events(self) -> list[Event]:
        return self.turbines.drain_events()

    # -- truth for scoring (cheap, no copies) -----------------------------------------------------------------
    def power_output(self) -> np.ndarray:
        """True electrical power output of every turbine at this tick, W (n,)."""
        return self.turbines.power_output()

    def shaft_torque(self) -> np.ndarray:
        """True low-speed shaft torque of every turbine at this tick, N m (n,)."""
        return self.turbines.shaft_torque()

    @property
    def blade_torque(self) -> np.ndarray:
        """True aerodynamic torque of each blade at this tick, N m (n, 3)."""
        return self.turbines.blade_torque

    # -- internals --------------------------------------------------------------------------------------------
    def _vane_noise_now(self) -> np.ndarray:
        """One unit-variance draw per run from the vane's own noise stream (drawn 1000 samples at a time)."""
        if self._vane_noise_chunk.shape[1] == 0:
            self._vane_noise_chunk = np.stack([rng.standard_normal(1000) for rng in self._vane_noise])
        out, self._vane_noise_chunk = self._vane_noise_chunk[:, 0], self._vane_noise_chunk[:, 1:]
        return out

    def _mast_noise_now(self) -> np.ndarray:
        """One unit-variance draw per run from the mast's own noise stream (drawn 1000 samples at a time)."""
        if self._mast_noise_chunk.shape[1] == 0:
            self._mast_noise_chunk = np.stack([rng.standard_normal(1000) for rng in self._mast_noise])
        out, self._mast_noise_chunk = self._mast_noise_chunk[:, 0], self._mast_noise_chunk[:, 1:]
        return out
