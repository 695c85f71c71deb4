"""The built-in turbine algorithms, registered by name.

Detectors: ``benchmark`` (the default: ``uio-bank`` plus the pitch-sensor, pitch-actuator and converter tests of
``component_fdi``), ``uio-bank`` (seed 000's bank with the speed-sensor FDI of ``fdi``), ``none``.
Estimators: ``uio-bank`` (the observer matching the healthy set, wind from ``wind_recovery``), ``none``
(passes the raw sensors through, i.e. the benchmark controller as published).

Options are declared at registration (``service.plugins``): the detectors' are the fields of ``FDISettings`` (and,
prefixed ``component_``, of ``ComponentSettings``), the estimator's those of ``EstimatorSettings``; a field added
to one of these dataclasses is an option at once. ``none`` declares none.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from scipy.stats import norm

from service.plugins import TURBINE_DETECTORS, TURBINE_ESTIMATORS
from service.turbine.bank import GENERATOR, estimate_observers, power_speed_estimate_observers
from service.turbine.component_fdi import ComponentFDI
from service.turbine.component_settings import ComponentSettings
from service.turbine.encoder_compensation import EncoderFaultEstimate, ticks_until_better
from service.turbine.fdi import FDISettings, SpeedSensorFDI
from service.turbine.interfaces import (
    POWER_SPEED_DESIGN_TORQUES,
    POWER_SPEED_DETECTOR_DESIGNS,
    POWER_SPEED_MIN_TORQUE,
    SPEED_COLUMNS,
    Diagnosis,
    Estimates,
    TurbineContext,
    empty_diagnosis,
    power_speed_band,
    static_state_guess,
)
from service.turbine.wind_recovery import WindRecovery
from wwcore.backend import fast_module
from wwcore.channels import DIAGNOSIS_TARGETS, SENSOR_INDEX, SPEED_SENSORS, TARGET_INDEX
from wwcore.options import Bounds
from wwcore.turbine_frames import TurbineFrame

SPEED_TARGETS = np.array([TARGET_INDEX[s] for s in SPEED_SENSORS])
GENERATOR_TARGETS = np.array([TARGET_INDEX[s] for s in GENERATOR])
PITCH_M1 = np.array([SENSOR_INDEX[f"beta_{i}_m1"] for i in (1, 2, 3)])
PITCH_M2 = np.array([SENSOR_INDEX[f"beta_{i}_m2"] for i in (1, 2, 3)])
PITCH_M12 = np.concatenate([PITCH_M1, PITCH_M2])
PITCH_M1_T = np.array([TARGET_INDEX[f"beta_{i}_m1"] for i in (1, 2, 3)])
PITCH_M2_T = np.array([TARGET_INDEX[f"beta_{i}_m2"] for i in (1, 2, 3)])
CONVERTER_T = TARGET_INDEX["converter"]
_MASK_WEIGHTS = 1 << np.arange(len(SPEED_SENSORS))
_GENERATOR_BITS = tuple(int(_MASK_WEIGHTS[SPEED_SENSORS.index(s)]) for s in GENERATOR)  # in ``GENERATOR``'s order
_GENERATOR_SPEEDS = np.array([SPEED_SENSORS.index(s) for s in GENERATOR])  # their columns in the speed readings
# Diagnosis row of each speed-sensor bitmask (16, len(DIAGNOSIS_TARGETS)): one gather gives the whole verdict.
_P_G_M, _TAU_G_M = SENSOR_INDEX["p_g_m"], SENSOR_INDEX["tau_g_m"]
_DIAGNOSIS_OF_MASK = np.zeros((1 << len(SPEED_SENSORS), len(DIAGNOSIS_TARGETS)), dtype=bool)
_DIAGNOSIS_OF_MASK[:, SPEED_TARGETS] = (np.arange(1 << len(SPEED_SENSORS))[:, None] & _MASK_WEIGHTS) != 0


DETECTOR_OPTIONS = {"": FDISettings}
BENCHMARK_OPTIONS = {"": FDISettings, "component_": ComponentSettings}


@dataclass(frozen=True)
class EstimatorSettings:
    """Options of the ``uio-bank`` estimator (``[supervisor.params]``); ``Bounds``: the accepted range."""

    # the torque the wind inversion uses is low-pass filtered at this frequency
    wind_cutoff_hz: Annotated[float, Bounds(gt=0.0, le=5.0, unit="Hz")] = 0.3
    # low-pass of the speed estimates (sent to the controller in region 3, or without a generator-speed sensor)
    speed_cutoff_hz: Annotated[float, Bounds(gt=0.0, le=50.0, unit="Hz")] = 2.0
    warmup_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = 5.0  # estimates not valid before this
    wind_every: Annotated[int, Bounds(ge=1, le=1000, unit="ticks")] = 20  # the wind is inverted every this many ticks
    power_speed: bool = True  # both generator-speed sensors flagged: use observer 5-pe
    # "generator": observer 4 on the healthy generator-speed sensors; "seed000": the published selection
    estimate_from: Literal["generator", "seed000"] = "generator"
    # the encoders' consistency test (``UIOBankEstimator``): a healthy pair's two one-encoder torques differ beyond
    # its level on this share of the wind's inversions; 0: no test
    encoder_pair_alpha: Annotated[float, Bounds(ge=0.0, lt=1.0)] = 1e-3
    # one generator-speed encoder flagged: the wind's torque from both encoders, the flagged one's reading less an
    # estimate of its fault (``encoder_compensation``), once that is the quieter torque
    encoder_compensation: bool = True


def _settings(cls, options: dict):
    known = {k: v for k, v in options.items() if k in cls.__dataclass_fields__}
    return cls(**known)


@TURBINE_DETECTORS.register("uio-bank", options=DETECTOR_OPTIONS)
class UIOBankDetector:
    """Speed-sensor FDI on the residuals of seed 000's observer bank (see ``service.turbine.fdi``)."""

    def __init__(self, *, context: TurbineContext, options: dict | None = None):
        self.context = context
        settings = _settings(FDISettings, options or {})
        self.fdi = SpeedSensorFDI(context.bank_design, context.n, context.dt, settings, fast=context.fast)
        if self.fdi.calibration.enabled:  # the bank reads the speed sensors less their learnt offsets
            context.speed_calibration = self.fdi.calibration
        design = context.bank_design
        self._margin_names = tuple(f"observer {name}" for name in design.names[: design.n_isolating])
        torques = np.asarray(POWER_SPEED_DESIGN_TORQUES)  # the edges of ``power_speed_band``, for the fast path
        self._band_edges = np.sqrt(np.multiply(torques[:-1], torques[1:])) * context.params.rated_torque
        self._design_of_band = np.array(POWER_SPEED_DETECTOR_DESIGNS, dtype=np.int64)

    def power_speed_inputs(self, frame: TurbineFrame) -> tuple[np.ndarray, np.ndarray]:
        """The 5-pe design of each row's torque band for the isolation, clearing and arbitration
        (``POWER_SPEED_DETECTOR_DESIGNS`` of ``power_speed_band``) and the power-speed channel P_g,m/(η_gc τ_g,m),
        NaN where τ_g,m is below the channel's threshold: (n,) each."""
        p = self.context.params
        if self.context.fast is not None:  # the same, by one kernel
            channel, band = np.empty(self.context.n), np.empty(self.context.n, dtype=np.int64)
            self.context.fast.power_speed_test(
                frame.sensors, _P_G_M, _TAU_G_M, self.context.power_speed_min_torque, p.eta_gc, frame.tau_g_ref,
                frame.zone, self._band_edges, self._design_of_band, channel, band,
            )  # fmt: skip
            return band, channel
        power, torque = frame.sensors[:, _P_G_M], frame.sensors[:, _TAU_G_M]
        usable = torque >= POWER_SPEED_MIN_TORQUE * p.rated_torque
        band = self._design_of_band[power_speed_band(frame.tau_g_ref, p, frame.zone)]
        return band, np.where(usable, power / (p.eta_gc * np.where(usable, torque, 1.0)), np.nan)

    def step(self, frame: TurbineFrame) -> Diagnosis:
        bank = self.context.bank(frame)
        speed = self.context.speed_readings(frame)
        band, channel = self.power_speed_inputs(frame)
        self.fdi.step(speed, bank.chi2, bank.x_hat, band, channel)
        return self.diagnosis()

    def diagnosis(self) -> Diagnosis:
        """The speed FDI's verdict after its step: the speed-sensor columns ``fdi.faulty``, margins its ratio
        max(χ²_j/h_j, Σχ²_j/h_window,j) (above 1: inconsistent), while an isolation is pending the suspects."""
        fdi = self.fdi
        suspect = None  # read only while an isolation is pending; the fast path skips it otherwise
        if fdi.pending or self.context.fast is None:
            suspect = _DIAGNOSIS_OF_MASK[np.where(fdi.deadline >= 0, fdi.flagged | fdi.provisional, fdi.flagged)]
        return Diagnosis(
            _DIAGNOSIS_OF_MASK[fdi.flagged], fdi.ratio, self._margin_names, suspect if fdi.pending else None
        )


@TURBINE_DETECTORS.register("benchmark", options=BENCHMARK_OPTIONS)
class BenchmarkDetector(UIOBankDetector):
    """``uio-bank`` for the speed sensors plus ``component_fdi``'s tests for the benchmark's other faults."""

    def __init__(self, *, context: TurbineContext, options: dict | None = None):
        super().__init__(context=context, options=options)
        settings = _settings(
            ComponentSettings,
            {k[len("component_") :]: v for k, v in (options or {}).items() if k.startswith("component_")},
        )
        self.components = ComponentFDI(context.params, context.n, context.sensor_sigma, settings, fast=context.fast)

    def step(self, frame: TurbineFrame) -> Diagnosis:
        return self.with_components(super().step(frame), self.components.step(frame))

    @staticmethod
    def with_components(diagnosis: Diagnosis, flags: np.ndarray) -> Diagnosis:
        """The speed FDI's ``diagnosis`` with the component tests' ``flags`` added."""
        diagnosis.faulty |= flags
        if diagnosis.suspect is not None:
            diagnosis.suspect |= flags
        return diagnosis

    def folded(self, estimator) -> object | None:
        """The compiled tick in one call with ``uio-bank`` ``estimator``'s (``fast_supervisor.FoldedTick``), or None."""
        if self.context.fast is None or not isinstance(estimator, UIOBankEstimator):
            return None
        constants = (_DIAGNOSIS_OF_MASK, _P_G_M, _TAU_G_M, PITCH_M12)
        return fast_module("service.turbine.fast_supervisor").FoldedTick(self, estimator, constants)


@TURBINE_DETECTORS.register("none")
class NoDetector:
    """Flags nothing: the supervisor then always uses observer 1 (the non-fault-tolerant estimator)."""

    def __init__(self, *, context: TurbineContext, options: dict | None = None):
        self.n = context.n

    def step(self, frame: TurbineFrame) -> Diagnosis:
        return empty_diagnosis(self.n)


@TURBINE_ESTIMATORS.register("uio-bank", options=EstimatorSettings)
class UIOBankEstimator:
    """Estimates of the observer chosen by the trusted speed sensors (active fault tolerance).

    Options (``EstimatorSettings``): ``wind_cutoff_hz`` (default 0.3), ``speed_cutoff_hz`` (2.0), ``warmup_s``
    (5.0), ``wind_every`` (20): the wind is inverted every that many ticks (5 Hz) and held in between; the torque
    it inverts is low-pass filtered at ``wind_cutoff_hz``, far below the 5 Hz this resolves. ``power_speed``
    (true): with both generator-speed sensors flagged, use the observer of the torque band
    (``interfaces.power_speed_band``, ``bank.power_speed_estimate_observers``): observer 5-pe (the rotor-speed
    sensors and the power-speed channel, ``docs/turbine.md``), the design for the torque reference and zone, instead
    of seed 000's observer 5, except in region 1, below the channel's threshold, where the channel is the rotor-speed
    sensors' mean and observer 5 serves. ``estimate_from`` (``"generator"``): the estimate comes from observer 4,
    the rigid drive train on the healthy generator-speed sensors (4 with both, 4-g1 or 4-g2 with one), which never
    uses a rotor-speed sensor, so a rotor-speed fault cannot reach it whether or not it is flagged; only with both
    generator-speed sensors flagged does it fall back to the rotor-speed sensors (5-pe or 5). ``"seed000"``: the
    observer whose sensor set matches the healthy sensors, as published (observer 1 when nothing is flagged).
    ``encoder_compensation`` (true): with one generator-speed sensor flagged, the wind's torque from both encoders,
    the flagged one's reading less an estimate of its fault (``_compensate``, ``encoder_compensation``).
    """

    def __init__(self, *, context: TurbineContext, options: dict | None = None):
        settings = _settings(EstimatorSettings, options or {})
        self.context = context
        design = context.bank_design
        self.recovery = WindRecovery(
            context.params,
            design,
            context.n,
            wind_cutoff_hz=settings.wind_cutoff_hz,
            speed_cutoff_hz=settings.speed_cutoff_hz,
            fast=context.fast,
        )
        self.warmup_ticks = round(settings.warmup_s / context.dt)
        self.wind_every = settings.wind_every
        self.observer_of_mask = estimate_observers(design, settings.estimate_from == "generator", settings.power_speed)
        # With both generator-speed sensors flagged: the observer of the row's torque band (``select``)
        self._observer_of_band = power_speed_estimate_observers(design, settings.power_speed)
        torques = np.asarray(POWER_SPEED_DESIGN_TORQUES)  # the edges of ``power_speed_band``, for the fast path
        self._band_edges = np.sqrt(np.multiply(torques[:-1], torques[1:])) * context.params.rated_torque
        self._previous: np.ndarray | None = None  # ``selected`` of the last tick
        self._previous_mask = np.zeros(context.n, dtype=np.int64)  # the distrusted speed sensors of the last tick
        # the distrusted speed sensors that were flagged (not only suspected) at some tick since they were distrusted
        self._tainted = np.zeros(context.n, dtype=np.int64)
        self._switched = False  # whether any row distrusted a speed sensor at the last tick
        self.reference = design.reference
        self._reference_columns = np.full(context.n, design.reference)
        self._all_healthy = np.full(context.n, self.observer_of_mask[0])  # ``selected`` when nothing is flagged
        # ``Estimates.selected`` and ``valid`` (before, after the warm-up) of the common compiled tick: arrays that
        # are handed out every such tick and never written
        self._healthy_selected = self._all_healthy.copy()
        self._healthy_valid = (np.zeros(context.n, dtype=bool), self._all_healthy >= 0)
        self._rows = np.arange(context.n)
        self.names = design.names
        self.ticks = 0
        self._winds: np.ndarray | None = None  # (2, n): FTE, NFTE
        self._inverted: np.ndarray | None = None  # (n,) the FTE's observer at the last inversion
        self._no_move = np.zeros(context.n, dtype=bool)  # the NFTE's observer never changes
        # The encoders' consistency test (``_wind_columns``): the two one-encoder observers (4-g1, 4-g2), the
        # observer on both (4), and the level of their torques' difference at the two-sided encoder_pair_alpha.
        self._pair_level = np.inf
        both = self.observer_of_mask[0]
        pair = tuple(design.single_generator)
        if settings.encoder_pair_alpha > 0.0 and len(pair) == 2 and settings.estimate_from == "generator":
            sigma = self.recovery.pair_difference_sigma(design, pair)
            self._pair_level = float(norm.isf(settings.encoder_pair_alpha / 2.0)) * sigma
        self._pair, self._both_encoders = pair, both
        self._fault_estimate: EncoderFaultEstimate | None = None
        if settings.encoder_compensation and len(pair) == 2 and settings.estimate_from == "generator":
            self._fault_estimate = self._encoder_fault_estimate(design, context)
        self._corrected = np.zeros(context.n, dtype=bool)  # rows with a column on the corrected pair (``_compensate``)
        self._compensated = np.zeros(context.n, dtype=bool)  # rows whose wind's torque is that column's
        self._compensated_inverted = np.zeros(context.n, dtype=bool)  # ``_compensated`` at the last inversion

    def healthy_ready(self) -> bool:
        """Whether ``step`` begins with the common compiled tick's call (``WindRecovery.step_healthy``): compiled,
        nothing to hand over (no speed sensor distrusted last tick), no encoder compensation running."""
        active = self._fault_estimate is not None and self._fault_estimate.active
        return self.context.fast is not None and not (self._switched or active)

    def _encoder_fault_estimate(self, design, context: TurbineContext) -> EncoderFaultEstimate:
        """The fault estimate of a flagged generator-speed encoder (``encoder_compensation``), with the ticks from
        which the corrected pair makes a quieter torque than the healthy encoder alone (``ticks_until_better``). Kept
        for ``_compensate``: each encoder's one-encoder observer (``_own``: the column that carries the corrected pair
        while that encoder is flagged), its x̂ block and H (``_own_block``, ``_own_gain``: x̂ = … + h y), and observer
        4's inverse-variance weight of the encoder (``_own_weight``)."""
        both = design.observers[self._both_encoders]
        sensors = [both.sensors.index(g) for g in GENERATOR]
        self._own = np.array(self._pair[::-1])  # single_generator[k] leaves out encoder k: [1 − k] runs on it
        self._own_block = [
            slice(design.offsets[j], design.offsets[j] + design.observers[j].n_states) for j in self._own
        ]
        self._own_gain = [design.observers[j].H[:, 0].copy() for j in self._own]
        self._own_weight = [float(both.H[1, i]) for i in sensors]
        sigma = np.sqrt(np.diag(both.R)[sensors])
        cutoffs = self.recovery.torque_cutoffs_hz
        ticks = []
        for k in range(2):
            own = int(self._own[k])
            c_now, c_prev = self.recovery.rigid_speed_coefficients(design, own)
            sigmas = (float(sigma[1 - k]), float(sigma[k]))  # the healthy encoder's, the flagged one's
            cutoff, healthy_cutoff = float(cutoffs[own]), float(cutoffs[self._pair[k]])
            ticks.append(
                ticks_until_better(c_now, c_prev, self._own_weight[k], *sigmas, cutoff, healthy_cutoff, context.dt)
            )
        # −1 (never) for either encoder: never; else the later of the two (the same where the σ are alike)
        return EncoderFaultEstimate(context.n, context.dt, float(np.hypot(*sigma)), -1 if -1 in ticks else max(ticks))

    def _compensate(self, bank, mask: np.ndarray, flagged: np.ndarray, frame: TurbineFrame) -> np.ndarray:
        """The x̂ the wind recovery runs on this tick: the bank's, except on the rows where one generator-speed encoder
        is flagged (``flagged``, bitmasks per row), the other trusted (``mask``: the distrusted speed sensors), and
        its fault estimate predicts (``EncoderFaultEstimate.step``): there the flagged encoder's own one-encoder
        observer (4-g2 for ω_g,m1, 4-g1 for ω_g,m2), which the estimate does not use while the flag lasts, reads the
        corrected pair instead, ω̂_g = (1 − w) y_h + w (y_f − d̂) with observer 4's weight w (x̂ + h (ω̂_g − y_f)). Its
        torque filter is the healthy encoder's observer's (the one-encoder cutoff), so the corrected pair's torque
        has that observer's lag and less noise. It is fed from the estimate's start, and a row that starts takes
        over the healthy encoder's observer's filters (``WindRecovery.transfer``), which have forgotten the
        estimate's first, noisy predictions by the time the wind uses it (``_compensated``:
        ``EncoderFaultEstimate.ready``). The bank's x̂ itself is not changed: the detector, the controller's speeds
        and the other columns read the raw readings."""
        estimate = self._fault_estimate
        generator = mask & (_GENERATOR_BITS[0] | _GENERATOR_BITS[1])
        encoder = np.full(self.context.n, -1, dtype=np.int64)
        for k, bit in enumerate(_GENERATOR_BITS):
            encoder[(generator == bit) & (flagged & bit != 0)] = k
        if not (encoder >= 0).any():
            self._stop_compensation()
            return bank.x_hat
        speeds = self.context.speed_readings(frame)[:, _GENERATOR_SPEEDS]
        if self.context.speed_offset is not None:  # the bank's readings
            speeds = speeds - self.context.speed_offset[:, _GENERATOR_SPEEDS]
        which = np.maximum(encoder, 0)
        faulty, healthy = speeds[self._rows, which], speeds[self._rows, 1 - which]
        use = estimate.step(encoder, faulty, healthy)
        started = use & ~self._corrected
        self._corrected = use
        self._compensated = estimate.ready.copy()
        if not use.any():
            return bank.x_hat
        x_hat = bank.x_hat.copy()
        for k in range(2):
            rows = np.flatnonzero(use & (encoder == k))
            if len(rows):
                w = self._own_weight[k]
                shift = (1.0 - w) * (healthy[rows] - faulty[rows]) - w * estimate.prediction[rows]  # ω̂_g − y_f
                x_hat[rows, self._own_block[k]] += shift[:, None] * self._own_gain[k]
        if started.any():
            rows = np.flatnonzero(started)
            source = np.asarray(self._pair)[encoder[rows]]  # the healthy encoder's observer
            self.recovery.transfer(rows, self._own[encoder[rows]], source, self.context.bank_design, x_hat)
        return x_hat

    def _stop_compensation(self) -> None:
        """No row has one generator-speed encoder flagged: the fault estimate stops and no column is corrected."""
        self._fault_estimate.stop()
        self._corrected[:] = False
        self._compensated[:] = False

    def _take_over(self, bank, selected: np.ndarray, mask: np.ndarray, flagged: np.ndarray) -> None:
        """Where a speed sensor that was flagged is trusted again (``mask``: the distrusted speed sensors, ``flagged``:
        those of them the detector has flagged, bitmasks per row), the observer the estimate moves to restarts from
        the previous one's state and filters (``ObserverBank.restart``, ``WindRecovery.transfer``): it ran on the
        faulty readings all along, and its filtered torque still carries them for seconds (the wind filter's 0.3 Hz).

        A sensor that was only suspected (an isolation considered it and named another) is trusted again without
        a take-over: the detector found its readings healthy, so the observer that uses it has run on healthy
        readings, and its own filters are the right ones. Handing it the previous observer's would throw away what
        its filters hold of its own torque (on a ringing drive train, the 4.5 Hz torsion the rigid observers see and
        the Kalman designs do not: up to 3 MN m of filtered torque for a second, ``docs/turbine.md``)."""
        previous, previous_mask = self._previous, self._previous_mask
        self._previous, self._previous_mask = selected, mask
        tainted = self._tainted | flagged
        self._tainted = tainted & mask  # a sensor trusted again starts clean
        fast = self.context.fast
        if fast is not None and previous is not None:  # the tests below, at once, for the common tick
            self._switched, moving = fast.handover(previous, previous_mask, selected, mask)
            if not moving:
                return
        self._switched = bool(mask.any())
        if previous is None:
            return
        restored = previous_mask & ~mask & tainted
        rows = np.flatnonzero((restored != 0) & (selected != previous) & (selected >= 0) & (previous >= 0))
        if len(rows):
            bank.restart(rows, selected[rows], previous[rows])
            self.recovery.transfer(rows, selected[rows], previous[rows], self.context.bank_design, bank.x_hat)
        self._restart_encoder_pair(restored, mask, bank.x_hat)

    def _restart_encoder_pair(self, restored: np.ndarray, mask: np.ndarray, x_hat: np.ndarray) -> None:
        """Where a flagged generator-speed sensor is trusted again (``restored``: the speed sensors trusted again
        this tick that were flagged, ``mask``: those still distrusted, bitmasks per row) while the other encoder is
        trusted and was not restored with it, the one-encoder observer on the restored encoder takes the other one's
        filters (``WindRecovery.transfer``), so the encoders' consistency test (``_wind_columns``) starts again from
        their noise.

        Why: that observer ran on the faulty readings all along, and its filtered torque carries the fault's end (a
        step of the offset or gain that ended) for seconds after its flag clears (the wind filter's 0.3 Hz); the
        test would read that as the encoders disagreeing and keep the wind off observer 4 on a healthy pair. The
        healthy encoder's observer has seen the same shaft with healthy readings, which is what the restored one's
        filters would hold had it never seen the fault. A sensor only suspected keeps its own filters (its readings
        were found healthy, ``_take_over``). Where the estimate moves, ``_take_over``'s own transfer and this one are
        on different columns; in the "generator" selection a restored encoder whose partner is trusted always moves
        the estimate (off the partner's one-encoder observer), so the compiled ``handover``'s test finds the tick."""
        if not np.isfinite(self._pair_level):
            return
        if not (restored & (_GENERATOR_BITS[0] | _GENERATOR_BITS[1])).any():
            return
        for k, bit in enumerate(_GENERATOR_BITS):
            partner = _GENERATOR_BITS[1 - k]
            rows = np.flatnonzero((restored & bit != 0) & (mask & partner == 0) & (restored & partner == 0))
            if len(rows):
                # single_generator[k] leaves out encoder k (it runs on the partner); [1 − k] runs on encoder k
                on_restored = np.full(len(rows), self._pair[1 - k])
                on_partner = np.full(len(rows), self._pair[k])
                self.recovery.transfer(rows, on_restored, on_partner, self.context.bank_design, x_hat)

    def select(
        self, faulty: np.ndarray, torque_reference: np.ndarray, zone: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The bitmask of the distrusted speed sensors (``faulty``: (n, targets) bool) and the observer each row's
        estimate comes from (n,) each: ``observer_of_mask``'s, and with both generator-speed sensors distrusted the
        observer of the row's torque band (``power_speed_band`` of the torque reference and the controller's zone,
        ``bank.power_speed_estimate_observers``). Compiled: ``fast.select_observers``, the same numbers."""
        fast = self.context.fast
        if fast is not None:
            n = len(faulty)
            mask, selected = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
            fast.select_observers(
                faulty, SPEED_TARGETS, _MASK_WEIGHTS, self.observer_of_mask, self._observer_of_band, torque_reference,
                zone, self._band_edges, self.context.power_speed_min_torque, mask, selected,
            )  # fmt: skip
            return mask, selected
        mask = faulty[:, SPEED_TARGETS] @ _MASK_WEIGHTS
        selected = self.observer_of_mask[mask]
        if len(self._observer_of_band):
            on_band = selected == self._observer_of_band[0]
            if on_band.any():
                band = power_speed_band(torque_reference, self.context.params, zone)
                selected = np.where(on_band, self._observer_of_band[band], selected)
        return mask, selected

    def _wind_columns(self, columns: np.ndarray, faulty: np.ndarray, frame: TurbineFrame) -> np.ndarray:
        """The observer each row's wind is inverted from: ``columns`` (the estimate's observer), except on the rows
        on both generator-speed sensors (observer 4) whose two one-encoder observers' filtered torques differ by more
        than ``_pair_level``: those take the observer the estimate uses with both encoders distrusted (``select``:
        observer 5 in region 1, the torque band's 5-pe above).

        Why: while nothing is suspected observer 4 averages the two encoders, so an encoder fault the detector has
        not yet seen (a small offset's step, a drift) moves its torque by half what it does to the faulty encoder's
        own observer, and at low wind a torque error moves the wind estimate most (``docs/turbine.md``, "The
        encoders' consistency test"). The two one-encoder torques' difference is the encoders' noise alone on a
        healthy plant, whatever the wind (``WindRecovery.pair_difference_sigma``), so the level is its two-sided
        ``encoder_pair_alpha`` quantile: a healthy pair leaves observer 4 on that share of the inversions. A fault
        on one encoder moves the difference by the whole of what it does to that encoder's observer, twice what it
        does to observer 4's torque, and the estimate leaves both encoders until the two agree again. The speeds
        sent to the controller and ``selected`` are not changed; a rotor-speed fault does not move the difference."""
        if not np.isfinite(self._pair_level):
            return columns
        on_both = columns == self._both_encoders
        if not on_both.any():
            return columns
        torque = self.recovery.filtered
        apart = on_both & (np.abs(torque[:, self._pair[0]] - torque[:, self._pair[1]]) > self._pair_level)
        if not apart.any():
            return columns
        distrusted = faulty.copy()
        distrusted[np.ix_(np.flatnonzero(apart), GENERATOR_TARGETS)] = True
        _, fallback = self.select(distrusted, frame.tau_g_ref, frame.zone)
        return np.where(apart & (fallback >= 0), fallback, columns)

    @staticmethod
    def _flagged_mask(flagged: np.ndarray | None, mask: np.ndarray) -> np.ndarray:
        """The flagged speed sensors among the distrusted ones (``mask``), as bitmasks; all of them without
        ``flagged``."""
        if flagged is None:
            return mask
        return (flagged[:, SPEED_TARGETS] @ _MASK_WEIGHTS) & mask

    def step(
        self, frame: TurbineFrame, faulty: np.ndarray, flagged: np.ndarray | None = None, healthy=None
    ) -> Estimates:
        """``faulty``: the targets not to use (flagged or suspected); ``flagged``: those of them the detector has
        flagged (None: all of them), which decides whether a sensor trusted again hands over (``_take_over``).
        ``healthy``: the common compiled tick's outcome where a caller's kernel made its call (``fast_supervisor``):
        (ω̂_r, ω̂_g) (``WindRecovery.healthy_ticked``), or False (a target distrusted: nothing done); None: not made."""
        bank = self.context.bank(frame)
        if self.ticks == 0:
            p = self.context.params
            x0 = static_state_guess(p, frame.sensors[:, SPEED_COLUMNS], frame.tau_g_ref)
            tau_aero0 = p.N_g * (p.B_g * x0[:, 1] + x0[:, 3]) / p.eta_dt + p.B_r * x0[:, 0]
            self.recovery.start(bank.x_hat, frame.beta_ref, tau_aero0)
            self._winds = np.tile(np.maximum(frame.sensors[:, SENSOR_INDEX["v_hub_m"]], 3.0), (2, 1))
        recovery = self.recovery
        fast = self.context.fast
        speeds = healthy or None  # the common compiled tick's (ω̂_r, ω̂_g)
        if healthy is None and self.healthy_ready():
            # every row on the observer that uses all four speed sensors, nothing to hand over or stop: the recovery's
            # step, the speeds' gather and region 2's below by one kernel call, unless a target is distrusted
            speeds = recovery.step_healthy(
                faulty, bank.x_hat, frame.beta_ref, frame.sensors, PITCH_M12, self._all_healthy, frame.zone
            )  # fmt: skip
        distrusting = speeds is None and bool(faulty.any())
        if distrusting or fast is None:
            pitch = frame.sensors[:, PITCH_M12]  # [β_i,m1 | β_i,m2], one gather
            pitch_m1, pitch_m2 = pitch[:, :3], pitch[:, 3:]
        if speeds is not None:
            (omega_r, omega_g), selected, columns = speeds, self._healthy_selected, self._all_healthy
        elif distrusting:
            mask, selected = self.select(faulty, frame.tau_g_ref, frame.zone)
            flagged_mask = self._flagged_mask(flagged, mask)
            self._take_over(bank, selected, mask, flagged_mask)
            x_hat = bank.x_hat if self._fault_estimate is None else self._compensate(bank, mask, flagged_mask, frame)
            recovery.step(
                x_hat, frame.beta_ref, pitch_m1, pitch_m2, ~faulty[:, PITCH_M1_T], ~faulty[:, PITCH_M2_T],
                _converter_torque(frame, faulty),
            )  # fmt: skip
            columns = np.maximum(selected, 0)
            if fast is not None:
                n = self.context.n
                omega_r, omega_g = np.empty(n), np.empty(n)
                fast.gather_speeds(recovery.filtered, *recovery.speed_starts, selected, omega_r, omega_g)
            else:
                rows = self._rows
                omega_r, omega_g = recovery.omega_r[rows, columns], recovery.omega_g[rows, columns]
        else:  # every sensor healthy, every row on the observer that uses all four speed sensors
            selected = self._all_healthy.copy()  # new: ``_take_over`` keeps it
            if self._fault_estimate is not None and self._fault_estimate.active:
                self._stop_compensation()
            if self._switched:
                none = np.zeros(len(selected), dtype=np.int64)
                self._take_over(bank, selected, none, none)
            columns = self._all_healthy
            if fast is not None:  # the common compiled tick's kernel, after the hand-over
                omega_r, omega_g = recovery.step_healthy(
                    faulty, bank.x_hat, frame.beta_ref, frame.sensors, PITCH_M12, selected, frame.zone
                )  # fmt: skip
            else:
                recovery.step(bank.x_hat, frame.beta_ref, pitch_m1, pitch_m2, None, None)
                healthy = int(columns[0])
                omega_r, omega_g = recovery.omega_r[:, healthy].copy(), recovery.omega_g[:, healthy].copy()
        if fast is None or distrusting:  # the common compiled tick did this in its kernel
            # region 2: the encoders' unfiltered speed, which lets the controller damp the torsion mode (the
            # method's note)
            omega_g = recovery.region2_generator_speed(bank.x_hat, selected, frame.zone, omega_g)
        if self.ticks % self.wind_every == 0:
            columns = self._wind_columns(columns, faulty, frame)
            if self._fault_estimate is not None and self._fault_estimate.active:
                # the fault estimates' residual test over the ticks since the last inversion; where the corrected
                # reading no longer fits, the wind goes back to the healthy encoder's observer
                misfit = self._fault_estimate.test()
                self._corrected &= ~misfit
                self._compensated &= ~misfit
                own = self._own[np.maximum(self._fault_estimate.encoder, 0)]
                columns = np.where(self._compensated, own, columns)
                # the wind moving onto the corrected pair stays on the torque it came from (the take-over), so the
                # inversion is warm; off it, the corrected torque may be what no longer fits: afresh
                onto = self._compensated & ~self._compensated_inverted
                if onto.any() and self._inverted is not None:
                    self._inverted = np.where(onto, own, self._inverted)
            self._compensated_inverted = self._compensated.copy()
            # an estimate whose observer changed since the last inversion is inverted afresh (``WindRecovery.wind``)
            moved = None if self._inverted is None else np.stack([columns != self._inverted, self._no_move])
            # region 1 (the selection's band): the operating point is on τ(v)'s stalled branch
            stalled = frame.tau_g_ref < self.context.power_speed_min_torque
            # no observer leaves out every distrusted sensor (``select`` −1): the estimate holds its last value
            # rather than invert column 0's torque, which reads the distrusted sensors, and the next inversion on
            # the observer it had warm-starts from it
            unfit = selected < 0
            held = self._winds[0].copy() if unfit.any() else None
            self._winds = recovery.wind(np.stack([columns, self._reference_columns]), self._winds, moved, stalled)
            if held is not None:
                self._winds[0] = np.where(unfit, held, self._winds[0])
                if self._inverted is not None:
                    columns = np.where(unfit, self._inverted, columns)
            self._inverted = columns.copy()
        self.ticks += 1
        if speeds is None:
            valid = (selected >= 0) & (self.ticks > self.warmup_ticks)
        else:
            valid = self._healthy_valid[self.ticks > self.warmup_ticks]
        return Estimates(
            valid=valid,
            omega_r=omega_r,
            omega_g=omega_g,
            wind=self._winds[0],
            selected=selected,
            observer_names=self.names,
            wind_reference=self._winds[1],
        )


def _converter_torque(frame: TurbineFrame, faulty: np.ndarray) -> np.ndarray | None:
    """τ_g,m on the rows whose converter is distrusted, NaN elsewhere; None where none is (``WindRecovery.step``).
    A converter offset sits in the torque reference, so the torque sensor reads the generator's real torque."""
    distrusted = faulty[:, CONVERTER_T]
    if not distrusted.any():
        return None
    return np.where(distrusted, frame.sensors[:, _TAU_G_M], np.nan)


@TURBINE_ESTIMATORS.register("none")
class RawSensors:
    """No estimator: the controller keeps its own sensors; the 'estimates' are the raw first sensors."""

    def __init__(self, *, context: TurbineContext, options: dict | None = None):
        self.n = context.n

    def step(self, frame: TurbineFrame, faulty: np.ndarray) -> Estimates:
        y = frame.sensors
        return Estimates(
            valid=np.zeros(self.n, dtype=bool),
            omega_r=y[:, SENSOR_INDEX["omega_r_m1"]].copy(),
            omega_g=y[:, SENSOR_INDEX["omega_g_m1"]].copy(),
            wind=y[:, SENSOR_INDEX["v_hub_m"]].copy(),
            selected=np.full(self.n, -1),
        )
