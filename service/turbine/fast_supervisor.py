"""The compiled ``benchmark`` supervisor's common tick in one kernel call (``wwcore.backend``): the observer bank's
kept tick (``fast_bank.bank_tick_kept``), the power-speed channel and each row's 5-pe design
(``fast.power_speed_test``), the speed FDI's tick on the bank's fresh χ² and x̂ (``fast_detector.detector_tick_kept``),
the frame's β_ref into the pitch-actuator block and the component tests' tick (``fast.component_step_kept``), and
where that tick is quiet, the detector's verdict, the estimator's common tick (``fast_recovery.recovery_healthy_tick``)
and the supervisor's event test (``fast.record_unchanged``).

The kernels are the ones the separate calls run, on the same arguments and in an order with the same effects (the
component tests read only the frame and their own state, so their tick may precede the FDI's Python), so the numbers
are theirs to the last bit (``tests/test_fast_supervisor.py``). Each object hands over the arguments it keeps as its
``wwcore.kept.Kept`` struct (N-41), held by this call's own struct, so the call unboxes five structs in one and the
tick's fresh arrays. Python keeps each object's bookkeeping after the call (``ObserverBank.ticked``,
``SpeedSensorFDI.ticked``, ``ComponentFDI.ticked``, ``WindRecovery.healthy_ticked``), and where the kernel finds the
tick not quiet part-way (the FDI not finished or a bias flag raised, a suspicious or repeated pitch reading), each
object's lines go on from there on what the kernel wrote, as the separate calls' callers do.
"""

from __future__ import annotations

import numpy as np

from service.turbine.fast import component_step_kept, power_speed_test, record_unchanged
from service.turbine.fast_bank import bank_tick_kept
from service.turbine.fast_detector import detector_tick_kept
from service.turbine.fast_recovery import recovery_healthy_tick
from service.turbine.interfaces import Diagnosis
from wwcore.jit import kernel
from wwcore.kept import Kept


@kernel
def supervisor_tick(frame, fresh, state, tick, kept):
    """One compiled supervisor tick (module docstring). ``frame`` = (sensors, τ_g,r, β_ref, zone); ``fresh`` = the
    new arrays the kernels write (the bank's inputs and speed readings, χ², the power-speed channel and band, the
    FDI's ratio, the diagnosis); ``state`` = the per-tick arguments (z, y[n−1], the speed offset (the speed readings
    where there is none), the FDI's and the component tests' last readings (None: not tested), the recovery's
    x̂[n−1], the supervisor's flags and selected observers); ``tick`` = (subtract the offset, the FDI's tick, the
    component tests' tick, whether their tick changes no flag when nothing is suspicious or repeated
    (``ComponentFDI.settled``), whether the estimator's common tick may run (``UIOBankEstimator.healthy_ready``));
    ``kept.args`` = (the bank's, the FDI's, the component tests', the recovery's ``Kept``, and (the diagnosis of each
    speed-sensor bitmask, the β_ref block, the power-speed constants, the pitch columns, the estimator's healthy
    selection, the ``selected`` its common tick hands out)).

    Returns (z, out, the FDI's results, the component tests' results, quiet: the diagnosis written, the estimator's
    common tick: −1 not run, 0 a target distrusted (nothing done), 1 done; and then whether no event is due)."""
    sensors, tau_g_ref, beta_ref, zone = frame
    read, speed, chi2, channel, band, ratio, faulty = fresh
    z, y_prev, offset, previous, component_previous, x_prev, flags, selected = state
    subtract, detector, component, settled, estimate = tick
    bank_kept, detector_kept, component_kept, recovery_kept, own = kept.args
    diagnosis_of_mask, ref_block, power, pitch_columns, healthy_columns, healthy_selected = own
    z, out = bank_tick_kept(sensors, subtract, offset, speed, read, z, tau_g_ref, y_prev, chi2, bank_kept)
    power_col, torque_col, threshold, eta_gc, edges, designs = power
    power_speed_test(sensors, power_col, torque_col, threshold, eta_gc, tau_g_ref, zone, edges, designs, channel, band)
    x_hat = out[:, : z.shape[1]]
    detected = detector_tick_kept(speed, chi2[:, : ratio.shape[1]], x_hat, previous, detector, detector_kept, ratio)
    j = component[0]
    for r in range(beta_ref.shape[0]):
        ref_block[j, r] = beta_ref[r]
    ticked = component_step_kept(sensors, tau_g_ref, component, component_previous, component_kept)
    finished, raised = detected[0], detected[4]
    quiet = finished and not raised and settled and not ticked[0] and not ticked[1]
    healthy, unchanged = -1, False
    if quiet:
        flagged = detector_kept.args[0][0]
        component_flags = component_kept.args[6][1]
        for r in range(faulty.shape[0]):
            for c in range(faulty.shape[1]):
                faulty[r, c] = diagnosis_of_mask[flagged[r], c] | component_flags[r, c]
        if estimate:
            done = recovery_healthy_tick(
                faulty, x_hat, x_prev, sensors, beta_ref, zone, pitch_columns, healthy_columns, recovery_kept
            )
            healthy = 1 if done else 0
            if done:
                unchanged = record_unchanged(flags, faulty, selected, healthy_selected)
    return z, out, detected, ticked, quiet, healthy, unchanged


class FoldedTick:
    """``TurbineSupervisor.step``'s detector and estimator calls for a ``benchmark`` detector and a ``uio-bank``
    estimator on the compiled backend, with their common tick in one kernel call (``supervisor_tick``).
    ``constants`` = (the diagnosis of each speed-sensor bitmask, the columns of P_g,m and τ_g,m, the pitch columns
    [β_i,m1 | β_i,m2])."""

    def __init__(self, detector, estimator, constants: tuple):
        self.detector, self.estimator = detector, estimator
        self.context = detector.context
        self._constants = constants
        n = self.context.n
        self._n_observers = len(self.context.bank_design.names)
        self._targets = constants[0].shape[1]
        self._n = n
        self._kept: Kept | None = None  # ``supervisor_tick``'s struct (``_kept_arguments``)

    def step(self, frame, flags: np.ndarray, selected: np.ndarray) -> tuple | None:
        """The detector's step on ``frame`` and the start of the estimator's (``supervisor_tick``), the supervisor's
        ``flags`` and ``selected`` compared with the tick's where it is quiet: (the diagnosis, the estimator's
        ``healthy`` argument, True where no event is due else None). None, with nothing done, where the bank's step
        is not its kept call (its first ticks): the separate calls then take the tick."""
        context = self.context
        bank = context.steady_bank(frame.k)
        if bank is None:
            return None
        detector, estimator = self.detector, self.estimator
        fdi, components, recovery = detector.fdi, detector.components, estimator.recovery
        kept = self._kept
        if kept is None or recovery._healthy_arguments is not kept.args[3]:
            kept = self._kept_arguments()
        n = self._n
        offset = context.speed_offset
        read = np.empty((n, 6))
        speed = np.empty((n, 4)) if offset is not None else read[:, :4]
        chi2, faulty = np.empty((n, self._n_observers)), np.empty((n, self._targets), dtype=bool)
        channel, band = np.empty(n), np.empty(n, dtype=np.int64)
        previous, detector_tick = fdi.tick_inputs()
        j = components.ticks % components.s.block
        component_tick = components.tick_inputs(j)
        settled = components.settled(j)
        z, out, detected, ticked, quiet, healthy, unchanged = supervisor_tick(
            (frame.sensors, frame.tau_g_ref, frame.beta_ref, frame.zone),
            (read, speed, chi2, channel, band, fdi.ratio, faulty),
            (
                bank.z, bank._y_prev, speed if offset is None else offset, previous, components.readings.previous,
                recovery._x_prev, flags, selected,
            ),
            (offset is not None, detector_tick, component_tick, settled, settled and estimator.healthy_ready()),
            kept,
        )  # fmt: skip
        bank.ticked(z, out, read, chi2)
        context.bank_ticked(frame.k, speed)
        x_hat = bank.x_hat
        fdi.ticked(detected, speed, x_hat, band, channel)
        if quiet:  # the diagnosis the kernel wrote: no speed sensor flagged or pending, no flag changed below
            diagnosis = Diagnosis(faulty, fdi.ratio, detector._margin_names)
            components.ticked(j, *ticked)
        else:
            diagnosis = detector.with_components(detector.diagnosis(), components.ticked(j, *ticked))
        if healthy < 0:
            return diagnosis, None, None
        return diagnosis, healthy == 1 and recovery.healthy_ticked(x_hat), unchanged or None

    def _kept_arguments(self) -> Kept:
        """``supervisor_tick``'s struct: the objects' own (built here where not yet) and this call's constants."""
        detector, estimator = self.detector, self.estimator
        fdi, components = detector.fdi, detector.components
        if fdi._kept is None:
            fdi._kept = fdi._detector.detector_arguments(fdi)
        if components._kept is None:
            components._tick_arguments()
        context = self.context
        p = context.params
        diagnosis_of_mask, power_col, torque_col, pitch_columns = self._constants
        power = (power_col, torque_col, context.power_speed_min_torque, p.eta_gc, detector._band_edges)
        own = (
            diagnosis_of_mask, components._ref_block, (*power, detector._design_of_band), pitch_columns,
            estimator._all_healthy, estimator._healthy_selected,
        )  # fmt: skip
        self._kept = Kept((
            context._bank.kept, fdi._kept["packed"], components._kept["packed"], estimator.recovery.healthy_kept(), own
        ))  # fmt: skip
        return self._kept
