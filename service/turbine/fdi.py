"""Speed-sensor fault detection and isolation from the observer bank's residuals (seed 000, Section 3).

In the manner of Odgaard & Stoustrup (2010): each observer's residual is decoupled from the unknown input, so
it stays at its noise level unless a sensor it uses is faulty. The decision logic is a generalised observer
scheme on the bank, with hysteresis: a flag is raised by the residuals' consistency tests and dropped only by
evidence that its sensor is healthy again.

* **Consistency.** Observer j is consistent at tick n when both its whitened residual's χ² statistic
  χ²_j[n] = ‖W_j r_j[n]‖² and the sum of the last ``window`` of them stay below their thresholds. The sum is
  what catches small biases: a UIO cannot predict the rotor speed one tick ahead (any change might be
  aerodynamic torque), so a bias of a few σ on a rotor-speed sensor shows in the residuals only as the
  observers' states drift from it over several ticks.
* **Detection.** While the selected observer (the one that leaves out the flagged sensors) is consistent,
  nothing is raised. When it is not, a fault is detected.
* **Isolation.** The new flagged set is the smallest set containing the flagged and frozen sensors whose observer
  explains the data, i.e. is consistent at the isolation level α_iso (default 1e-3), ties broken by the smaller
  statistic over threshold (``explanations``). Isolation is a choice between explanations once a fault is known to be
  there, so it can afford a test far less strict than detection's: a second fault a few σ in size, too small to trip
  detection on its own, still rejects the observer that leaves out only the first, and a simultaneous pair is flagged
  together from the first tick. The price is a healthy sensor flagged with the faulty one with probability about α_iso
  per isolation; its flag then clears on its own (below). Where no such set passes, the detection level is used, and
  where no superset of the flags passes either, the whole bank is searched (an isolation that went wrong may be
  replaced). Where nothing passes at all, the flags grow to the least inconsistent superset, or stay where none is
  left: a flag drops only by its clearing test.
* **No fault.** A detection may be the noise alone (the detection tests spend their design budget), and no
  explanation then is the truth, while every one is consistent a few ticks later. So before choosing one, the
  isolation asks whether the observer that detected (the selected one: the all-sensor observer while nothing is
  flagged) is consistent again on the ticks after the detection's: its statistic summed over those k ticks,
  against the upper α_confirm/L quantile of a healthy k-tick sum (L looks, k = max(``isolation_delay``, 1) …
  ``window``; Bonferroni). Beyond it, the fault persists and the isolation goes on; within it for a whole window,
  the detection ends without a flag and the detection test re-arms; within it on fewer ticks, the decision waits a
  tick (the explanations suspected). A detection raised by noise alone thus ends in a flag with probability
  ≤ α_confirm (0.05). A frozen reading, or a flagged set no observer leaves out, is a fault without this test. The
  cost falls on faults whose residual the observers absorb within a window of the detection (rotor-speed offsets
  of a few σ): they end unflagged here and are left to the rotor-speed bias test.
* **Doubt.** A fault on a rotor-speed sensor shows in the UIOs only as their states drift from it, over several
  ticks, so at the deadline a rotor-speed gain beside a generator-speed fault may not yet reject the explanation
  that names the generator-speed sensor alone. When a witness of the chosen explanation fails the laxer level
  ``isolation_confirm_alpha`` (default 0.05), the decision waits one more tick, up to ``isolation_patience``
  ticks beyond the deadline, with the explanations considered suspected (so the estimate already leaves them
  out): a first flag that names only part of the faulty set is a wrong isolation, and one more tick is cheaper.
  An explanation that names no rotor-speed sensor (a double fault's rotor-speed gain, which the UIOs see only as
  their states drift) also waits on the rotor-speed sensors' sequential tests (``rotor_pair``: Wald's test of "both
  healthy" against "one biased by a design size", looked at on every tick, its join level Ville-bounded at α_iso,
  its release level at α_confirm): at the upper level the sensor the test names joins the flag, at the lower one
  the explanation is decided as it is. The price is time: about 10 ticks on a healthy pair. A frozen sensor's
  explanation: "Frozen signals" below.
* **Hold.** Once the fault is confirmed ("No fault" above), an isolation that waits on an explanation (the
  arbitration between the encoders, the rotor-speed pair's test, a doubt) holds it while the wait lasts: a choice
  re-made by tie-break on every tick of a long wait lands sooner or later on whatever has nothing to wait for. The
  held explanation is rejected only at the wait's level α_iso/N (N = ``arbitration_s``/Ts, the longest wait), which
  a true one reaches over its whole wait with probability ≤ α_iso per witness (Bonferroni); so rejected, the
  explanation consistent at α_iso takes its place where it keeps the held sensors, else the isolation starts afresh
  with its own "no fault" test and the arbitration's sums restarted (docs/decisions.md N-33). An explanation naming
  a frozen sensor is not held, nor one during a chance join's patience (below): both are re-explained each tick.
* **Chance joins.** Where the chosen explanation grows a smaller one (the flagged and frozen sensors and a sensor
  beside them) that is consistent at the detection level, only a witness between the isolation and the detection
  levels made the choice, which a healthy witness does with probability about α_iso a tick. The decision then waits
  a tick, up to ``isolation_delay`` + ``isolation_patience`` ticks since the isolation started, the choice re-made
  on each: a healthy sensor joins only if a witness is over α_iso on the deciding tick and again at the patience's
  end, about (n_w α_iso)² for n_w witnesses; a real second fault beyond the detection level joins at once, one
  between the levels at the patience's end (docs/decisions.md N-31 for a frozen reading, N-36 for any explanation).
* **Persistent rotor-speed bias.** Beside the window tests, Page's CUSUMs (a bank of shifts ``bias_shift``·2^k,
  k < ``bias_bank``) on the parity of the two rotor-speed sensors' exclusion residuals against the generator-speed
  Kalman filter (``bias_test``; ``rotor_bias_test``, ``bias_shift``) flag a bias of 1–2 σ that the UIOs take for
  aerodynamic torque, and the sum of the two residuals names the sensor, on rows where no rotor-speed sensor is
  flagged and no isolation is under way (this tick's isolations start first); beside a flagged generator-speed
  sensor they read the filter on the other one. The filter's prediction error, coloured and three times the
  design's near rated, is common to both residuals and cancels in the parity, so the threshold holds at every wind.
  The smallest shift exceeds the clearing's floor, so between the two a flag neither drops nor rises again
  (hysteresis).
* **Fault end.** A flag drops only when its sensor's CUSUM (``clearing``) has gathered enough evidence that the
  exclusion residual (the sensor against the selected observer's prediction, which never uses it) is back at
  zero mean, with a false-clear budget like the false-alarm one, and the observer that uses the sensor again
  is consistent over its last ``clear_window`` ticks at level ``clear_alpha`` (so that re-admitting the sensor
  does not trip detection again while that observer still carries the fault).
* **Frozen signals.** A reading that does not change at all for ``frozen_ticks`` ticks is flagged at once
  (fixed-value and stuck faults carry no noise; this also catches a fixed value that happens to equal the
  truth, which no residual can see), and its flag cannot drop while it stays frozen. Its isolation is decided
  on the tick the frozen test fires (the test has seen ``frozen_ticks`` of the fault already) and never waits for
  the generator-speed arbitration (``arbitration``), which a reading frozen near the truth would keep open for
  seconds; but where the flagged and frozen sensors alone are consistent at the detection level and a witness
  is over the isolation level, the decision waits as for any chance join ("Chance joins" above). It looks once at
  the rotor-speed pair (the sum's z against the isolation level in the pair's learnt spread): agreeing, it is
  decided alone; disagreeing, the sequential test ("Doubt" above) decides it as any other, so a healthy sensor
  joins only where the look (α_iso) and the test's level both pass, a few hundredths of α_iso (decisions N-42).
* **Which generator-speed sensor.** Where an explanation names one generator-speed sensor and the other is not
  ruled out, the isolation waits for the arbitration (``arbitration``): the fault's first ticks against the pair
  mean's own prediction, then sums against the rotor-speed sensors and the power-speed channel.

Thresholds come from the false-alarm budget (PARAMETERS.md d), not from fault data. A design rate of false
alarms per 1000 s (default 0.01: the requirement is 1, the aim none) gives α = rate·Ts/1000 per tick, split
evenly between the single-tick and the window test: h_j = χ²⁻¹_{rank_j}(1 − α/2), and for the window sum a
scaled χ², c·χ²_ν, with the sum's exact mean and variance from the residual's closed-form autocovariance
(Satterthwaite: c = Var/2E, ν = 2E²/Var; ``uio``). Isolation and the re-admission test use the same forms at
α_iso and α_clear.

Adaptive thresholds (``adaptive``): every statistic enters the tests as χ²_j/ŝ²_j, with ŝ²_j observer j's healthy
scale of χ²_j/rank_j (design 1) learnt with adaptation time ``adapt_time_s`` from rows with nothing flagged or
pending and every observer consistent, used within [1, ``max_noise_scale``²]. The speed sensors' calibration offsets
b̂_s are learnt on the same rows, against the redundant sensors (a rotor-speed sensor against the generator-speed
mean / N_g: their difference is dθ_Δ/dt, zero on average; a generator-speed sensor against the pair's mean), within
the channels' tolerance (rad/s), and subtracted from the bank's inputs (``TurbineContext.speed_offset``) and from the
readings the clearing and arbitration use; the clearing's exclusion residuals are divided by the row's noise scale
(ŝ of observer 1). A plant whose sensors are noisier than the design σ, or carry calibration biases, then keeps the
design false-alarm rate.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from service.turbine.adaptive import HealthySpread
from service.turbine.arbitration import GeneratorArbiter
from service.turbine.bank import BankDesign, estimate_observers
from service.turbine.bias_test import ROTOR, RotorBiasTest
from service.turbine.clearing import FlagClearing
from service.turbine.explanations import (
    BITS,
    GENERATOR_BITS,
    N_SPEED,
    ROTOR_BITS,
    SENSORS_OF_MASK,
    Explanations,
)
from service.turbine.fdi_settings import FDISettings
from service.turbine.frozen import FrozenReadings
from service.turbine.rotor_pair import RotorPairTest
from service.turbine.uio import window_threshold
from wwcore.backend import fast_module
from wwcore.channels import SPEED_SENSORS
from wwcore.planes import Planes, planes
from wwcore.quantiles import chi2_isf
from wwcore.scenario.mismatch import SENSOR_BIAS_TOLERANCE


class SpeedSensorFDI(Planes):
    """Flags faulty speed sensors for n turbines; ``faulty`` (n, 4) bool in SPEED_SENSORS order."""

    PLANES: ClassVar[dict[str, tuple]] = {"_flags": ("flagged", "deadline")}

    def __init__(self, bank: BankDesign, n: int, dt: float, settings: FDISettings = FDISettings(), fast=None):
        self.bank = bank
        self._fast = fast  # ``service.turbine.fast`` (``wwcore.backend``) or None
        self.s = settings
        self.n = n
        alpha = settings.false_alarms_per_1000s * dt / 1000.0
        ranks = bank.ranks[: bank.n_isolating]
        observers = bank.observers[: bank.n_isolating]

        def levels(level: float) -> tuple[np.ndarray, np.ndarray]:
            """Each observer's single-tick χ² threshold and window-sum threshold at α = ``level``, split evenly."""
            windows = [window_threshold(o.autocov, settings.window, level / 2.0) for o in observers]
            return chi2_isf(level / 2.0, ranks), np.array(windows)

        self.h_detect, self.h_window = levels(alpha)
        iso = max(settings.isolation_alpha, alpha)
        self.h_isolate, self.h_isolate_window = levels(iso)
        confirm = max(settings.isolation_confirm_alpha, iso)
        self.h_confirm, self.h_confirm_window = levels(confirm)
        # a held explanation's rejection (``Explanations.consistent`` at it): α_iso spread over the N ticks a wait
        # lasts at most
        self.h_held, self.h_held_window = levels(iso / max(round(settings.arbitration_s / dt), 1))
        # the "no fault" outcome (``_fault_persists``): the selected observer's statistic summed over the k ticks after
        # the detection's, at level α_confirm / L for each of the L looks (k = max(isolation_delay, 1) … window), so a
        # detection raised by noise alone still ends in a flag with probability ≤ α_confirm (Bonferroni)
        first_look = max(settings.isolation_delay, 1)
        self.fresh_alpha = confirm / (settings.window - first_look + 1)
        self.h_fresh = np.zeros((bank.n_isolating, settings.window + 1))
        for k in range(first_look, settings.window + 1):
            self.h_fresh[:, k] = [window_threshold(o.autocov, k, self.fresh_alpha) for o in observers]
        self.h_clear = np.array(
            [window_threshold(o.autocov, settings.clear_window, settings.clear_alpha) for o in observers]
        )
        predictors = estimate_observers(bank, from_generator=len(bank.single_generator) > 0)
        self._estimable = predictors >= 0  # masks for which some observer gives the estimate
        self.clearing = FlagClearing(
            bank,
            n,
            dt,
            settings.false_clears_per_1000s,
            settings.clear_floor,
            settings.fault_memory_s,
            predictors,
            fast,
        )
        # the rotor-speed bias test reads the exclusion residuals of the observer that predicts both rotor-speed
        # sensors without them and without the flagged generator-speed sensors (the generator-speed Kalman filters)
        self.bias: RotorBiasTest | None = None
        self._bias_predictor = np.full(1 << N_SPEED, -1, dtype=np.int64)  # flagged mask → predictor, −1 untested
        if settings.rotor_bias_test:
            self.bias = RotorBiasTest(
                n,
                self.clearing.column[:, list(ROTOR)],
                self.clearing.scale[:, list(ROTOR)],
                dt,
                settings.false_alarms_per_1000s,
                settings.bias_shift,
                settings.adapt_time_s,
                settings.max_noise_scale,
                fast,
                settings.bias_bank,
            )
            for mask in range(1 << N_SPEED):
                if mask & ROTOR_BITS:
                    continue  # a rotor-speed sensor is flagged: its clearing watches it
                j = int(predictors[mask | ROTOR_BITS])
                if j >= 0 and self.bias.usable(j):
                    self._bias_predictor[mask] = j
            if (self._bias_predictor < 0).all():
                self.bias = None  # no observer of this bank predicts the rotor speed without the rotor sensors
        self.spread = HealthySpread(
            (n, bank.n_isolating), dt, settings.adapt_time_s, settings.max_noise_scale, fast=fast
        )
        self._rank = np.asarray(ranks, dtype=float)
        # calibration offsets of the four speed sensors against the redundant ones (``adaptive``): the rotor-speed
        # sensors against the generator-speed mean / N_g, each generator-speed sensor against the pair's mean;
        # within the channels' calibration tolerance
        tolerance = np.array([SENSOR_BIAS_TOLERANCE[s] for s in SPEED_SENSORS])
        self.calibration = HealthySpread((n, N_SPEED), dt, settings.adapt_time_s, 1.0, tolerance, fast=fast)
        self._gear_ratio = bank.gear_ratio
        self._history = np.zeros((settings.window, n, bank.n_isolating))  # ring of the last χ² statistics
        self._window_sum = np.zeros((n, bank.n_isolating))
        self.warmup_ticks = round(settings.warmup_s / dt)
        self.explanations = Explanations(bank)
        self.observer_of_mask = self.explanations.observer_of_mask  # explanation (bitmask) → its observer
        self.witnesses = self.explanations.witnesses
        # the bitmask of flagged sensors per turbine and the tick at which a pending isolation is decided (−1: none),
        # the planes of one block (``wwcore.planes``), which the compiled tick takes
        self._flags = np.zeros((len(self.PLANES["_flags"]), n), dtype=np.int64)
        self._flags[1] = -1
        self.__dict__.update(planes(self._flags, self.PLANES["_flags"]))
        self.readings = FrozenReadings((n, N_SPEED), settings.frozen_ticks, fast=fast)
        self.ticks = 0
        self.ambiguous = np.zeros(n, dtype=bool)  # no consistent observer was found at the last search
        self._rows = np.arange(n)
        # Cheap state for the common tick on which no sensor is flagged or frozen (each skips a few numpy calls):
        self.ratio = np.zeros((n, bank.n_isolating))  # ``margins`` of the last step
        self._maybe_flagged = False  # False only while no row has a flagged sensor
        self.started = np.zeros(n, dtype=np.int64)  # tick at which the pending isolation started
        # the ticks after the detection's have shown the fault (``_fault_persists``)
        self.confirmed = np.zeros(n, dtype=bool)
        # the explanation a confirmed isolation last waited on (−1: none), kept until rejected at the wait's level
        self.held = np.full(n, -1, dtype=np.int64)
        # a chance join was waited out (``_isolate``): the choice is re-made on every tick up to the patience
        self.rechoosing = np.zeros(n, dtype=bool)
        # a frozen sensor's one look found the rotor-speed pair disagreeing: their sequential test decides
        # (``_doubtful``)
        self.pair_disagreed = np.zeros(n, dtype=bool)
        self.arbiter = GeneratorArbiter(bank, n, iso, dt, fast)
        self.arbitration_ticks = round(settings.arbitration_s / dt)
        # the rotor-speed sensors' sequential tests judge an explanation that names no rotor-speed sensor, on every
        # tick the isolation waits, at most as long as the generator-speed arbitration (``rotor_pair``)
        self.rotor_pair = RotorPairTest(self.arbiter, settings, iso, confirm, self.bias, self.arbitration_ticks)
        self.provisional = np.zeros(n, dtype=np.int64)  # the pending isolation's current explanation
        self._pending = False  # whether any row has a pending isolation
        self._all_healthy = int(self.observer_of_mask[0])  # the observer that leaves nothing out
        self._no_frozen = np.zeros(n, dtype=np.int64)
        # the compiled tick (``fast_detector``), its arguments kept between ticks, and whether the arbiter learns next
        self._detector = fast_module("service.turbine.fast_detector") if fast is not None else None
        self._kept: dict | None = None
        self._learns = False
        self._quiet = False  # ``tick_inputs`` left the repeat test to the kernel

    @property
    def faulty(self) -> np.ndarray:
        return SENSORS_OF_MASK[self.flagged]

    def step(
        self,
        y: np.ndarray,
        chi2_stat: np.ndarray,
        x_hat: np.ndarray,
        torque_band: np.ndarray | None = None,
        power_speed: np.ndarray | None = None,
    ) -> None:
        """Update the flags from speed readings y (n, 4), the bank's χ² statistics (n, n_obs), its stacked
        state estimates x̂ (n, width), the 5-pe design for the torque (``clearing``) and the power-speed
        channel (n,) (NaN where it is only the rotor-speed mean; ``arbitration``)."""
        raw = chi2_stat[:, : self.bank.n_isolating]
        if self._fast is not None:  # the lines below, and a healthy tick's bias test, by one kernel
            (previous, tick), kept = self.tick_inputs(), self._kept["packed"]
            detected = self._detector.detector_tick_kept(y, raw, x_hat, previous, tick, kept, self.ratio)
            return self.ticked(detected, y, x_hat, torque_band, power_speed)
        slot = self.ticks % self.s.window
        chi2_stat = raw / self.spread.scale2 if self.spread.enabled else raw  # χ²_j / ŝ²_j (``adaptive``)
        self._window_sum += chi2_stat - self._history[slot]
        self._history[slot] = chi2_stat
        any_frozen = self.readings.push(y)  # the raw readings: a frozen one stays frozen
        y_raw = y
        if self.calibration.enabled:  # the clearing and the arbitration see the bank's calibrated readings
            y = y - self.calibration.offset
        self.ticks += 1
        # the pair mean's history and its prediction error, for the onset's log-likelihood ratio (``arbitration``)
        self.arbiter.observe(y, (self.flagged == 0) & (self.deadline < 0))
        self.ratio = ratio = np.maximum(chi2_stat / self.h_detect, self._window_sum / self.h_window)
        exceeded = True  # the all-sensor observer's ratios are tested below with the others
        if self.spread.enabled:  # learn from rows with nothing flagged, pending or inconsistent
            healthy = (self.flagged == 0) & (self.deadline < 0) & (ratio <= 1.0).all(axis=1)
            self.spread.update_rows(raw / self._rank, healthy)
            generator = 0.5 * (y_raw[:, 2] + y_raw[:, 3])
            deviation = y_raw - np.column_stack([generator / self._gear_ratio] * 2 + [generator] * 2)
            self.calibration.update_rows(None, healthy, deviation)  # offsets only
        self._decide(exceeded, any_frozen, y, chi2_stat, ratio, x_hat, torque_band, power_speed)

    def tick_inputs(self) -> tuple:
        """``fast_detector.detector_tick_kept``'s ``previous`` (None: no repeat test) and ``tick`` (slot, the arbiter
        learns, a healthy tick may finish); ``self.ratio`` new (it leaves the tick), ``_kept`` built once."""
        self._kept = self._kept or self._detector.detector_arguments(self)
        readings, previous = self.readings, self.readings.previous
        self._quiet = quiet = not (readings.counting or readings.ticks < 2) and previous is not None
        healthy = self.ticks >= self.warmup_ticks and not (self._maybe_flagged or self._pending)
        self.ratio = np.empty(self._window_sum.shape)
        return (previous if quiet else None), (self.ticks % self.s.window, self._learns, healthy)

    def ticked(self, detected: tuple, y: np.ndarray, x_hat: np.ndarray, torque_band, power_speed) -> None:
        """``step``'s lines after its kernel (``detected``: ``detector_tick_kept``'s results on ``tick_inputs``): the
        frozen readings, the arbiter's count, and where the kernel did not finish, the decisions on what it wrote."""
        (finished, repeated, exceeded, growing, raised), kept = detected, self._kept
        any_frozen = self.readings.push(y, repeated if self._quiet else None)
        self.ticks += 1
        self._learns = self.arbiter.observed(growing)
        if finished:  # nothing inconsistent, frozen, flagged or pending: the bias test has run
            if raised:
                self._raise_bias(kept["over"])
                self._clear_raised(kept["y"] if self.calibration.enabled else y, x_hat, torque_band)
            return
        y = kept["y"] if self.calibration.enabled else y
        self._decide(exceeded, any_frozen, y, kept["chi2_stat"], self.ratio, x_hat, torque_band, power_speed)

    def _decide(self, exceeded: bool, any_frozen: bool, y, chi2_stat, ratio, x_hat, torque_band, power_speed) -> None:
        """``step``'s isolation, bias test and clearing after the window tests (``exceeded``: a ratio may exceed 1)."""
        if self.ticks <= self.warmup_ticks:
            return
        if not (exceeded or any_frozen or self._maybe_flagged or self._pending):
            if self.bias is not None and self._rotor_bias(y, x_hat):
                self._clear_raised(y, x_hat, torque_band)
            return  # nothing inconsistent, frozen, flagged or pending: what the lines below conclude on such a tick
        frozen_mask = self.readings.frozen @ BITS if any_frozen else self._no_frozen
        if self._maybe_flagged or self._pending:
            selected = self.observer_of_mask[self.flagged]
            inconsistent = (ratio[self._rows, np.maximum(selected, 0)] > 1.0) | (selected < 0)
        else:  # every row selects the observer that uses all four sensors
            inconsistent = ratio[:, self._all_healthy] > 1.0
        trouble = inconsistent | ((frozen_mask & ~self.flagged) != 0) if any_frozen else inconsistent
        if self._pending or trouble.any():
            self._isolate(trouble, inconsistent, chi2_stat, ratio, frozen_mask, y, torque_band, power_speed)
        if self.bias is not None:
            # after the isolations: a row whose trouble starts on this tick is the isolation's (its bias statistics
            # pause), so a double fault's rotor-speed half is not flagged alone a tick before the isolation names both
            self._rotor_bias(y, x_hat)
        if self._maybe_flagged:
            if self.flagged.any():
                self._clear(y, x_hat, frozen_mask, trouble | (self.deadline >= 0), torque_band)
            self._maybe_flagged = bool(self.flagged.any())

    def _rotor_bias(self, y: np.ndarray, x_hat: np.ndarray) -> bool:
        """Flag a rotor-speed sensor whose bias the CUSUM of ``bias_test`` finds, on rows where no rotor-speed
        sensor is flagged and nothing is being isolated; the flag then drops only by its clearing test. Whether
        any is raised."""
        over = self.bias.step_flags(y, x_hat, self.flagged, self.deadline, self._bias_predictor)
        if over is not None:
            self._raise_bias(over)
        return over is not None

    def _clear_raised(self, y: np.ndarray, x_hat: np.ndarray, torque_band) -> None:
        """``step``'s last lines on a tick where the bias test raised a flag and nothing else was up."""
        self._clear(y, x_hat, self._no_frozen, np.zeros(self.n, dtype=bool), torque_band)
        self._maybe_flagged = bool(self.flagged.any())

    def _raise_bias(self, over: np.ndarray) -> None:
        """Flag the rotor-speed sensors of ``over`` (n, 2) bool, ``RotorBiasTest.step_flags``'s."""
        rows = over.any(axis=1)
        raised = np.zeros((self.n, N_SPEED), dtype=bool)
        raised[:, list(ROTOR)] = over
        self.flagged[rows] |= (raised @ BITS)[rows]
        self.provisional[rows] = self.flagged[rows]
        self.clearing.start(raised)
        self.bias.reset(rows)
        self._maybe_flagged = True

    def _isolate(
        self,
        trouble: np.ndarray,
        inconsistent: np.ndarray,
        chi2_stat: np.ndarray,
        ratio: np.ndarray,
        frozen_mask: np.ndarray,
        y: np.ndarray,
        torque_band: np.ndarray | None,
        power_speed: np.ndarray | None,
    ) -> None:
        """Start an isolation where trouble begins; decide those whose ``isolation_delay`` has run out, unless
        the chosen explanation is in doubt (``isolation_patience``) or the choice between the two generator-speed
        sensors is still open (``arbitration``)."""
        start = trouble & (self.deadline < 0)
        # a reading frozen for ``frozen_ticks`` has already shown its fault for that long: no delay to wait out
        self.deadline[start] = self.ticks + np.where(inconsistent[start], self.s.isolation_delay, 0)
        self.started[start] = self.ticks
        # a frozen reading is a fault whatever the residuals say; a flagged set no observer leaves out has no test
        untestable = ((frozen_mask & ~self.flagged) != 0) | (self.observer_of_mask[self.flagged] < 0)
        self.confirmed[start] = untestable[start]
        self.held[start] = -1
        self.rechoosing[start] = False
        self.pair_disagreed[start] = False
        # the onset's jump names the generator-speed sensor unless one of the pair is flagged (``arbitration``)
        self.arbiter.reset(start, (self.flagged & GENERATOR_BITS) == 0)
        suspected = SENSORS_OF_MASK[self.flagged | self.provisional]
        trusted_power = None if power_speed is None else np.isfinite(power_speed)
        self.arbiter.step(
            y,
            None if power_speed is None else np.nan_to_num(power_speed),
            np.zeros(self.n, dtype=np.int64) if torque_band is None else torque_band,
            ~suspected[:, :2],
            trusted_power,
            ~SENSORS_OF_MASK[self.flagged][:, :2].any(axis=1),  # the pair is compared unless one is flagged
        )
        decided = self.arbiter.decided()
        rows = np.flatnonzero(self.deadline >= 0)
        isolate = np.maximum(chi2_stat[rows] / self.h_isolate, self._window_sum[rows] / self.h_isolate_window)
        confirm = np.maximum(chi2_stat[rows] / self.h_confirm, self._window_sum[rows] / self.h_confirm_window)
        held = np.maximum(chi2_stat[rows] / self.h_held, self._window_sum[rows] / self.h_held_window)
        patience = self.s.isolation_delay + self.s.isolation_patience
        before = self.flagged.copy()
        explanations = self.explanations
        for i, row in enumerate(rows):
            frozen = int(frozen_mask[row])
            explained = explanations.explained(ratio[row])
            explanation, self.ambiguous[row] = explanations.explain(
                int(self.flagged[row]), explained, explanations.explained(isolate[i]), frozen, isolate[i]
            )
            if self.held[row] >= 0:
                kept = int(self.held[row])
                # only a rejection at the wait's level α_iso/N ends the wait (module docstring, "Hold")
                if explanations.consistent(kept, held[i]):
                    explanation = kept  # not rejected at the wait's level: a tie-break on noise does not replace it
                elif explanations.grows(kept, explanation):
                    self.held[row] = -1  # a further fault beside it: the explanation consistent at α_iso takes over
                else:  # rejected, and not by a further fault beside it: the isolation starts afresh
                    self._restart(row)
                    continue
            if self.ticks >= self.deadline[row]:
                waited = self.ticks - self.started[row]
                if not self.confirmed[row]:
                    persists = self._fault_persists(row, waited)
                    if persists < 0:  # no fault: the detection ends without a flag and the detection test re-arms
                        self.deadline[row] = -1
                        self.provisional[row] = self.flagged[row]
                        continue
                    if persists == 0:  # too few ticks since the detection to tell
                        self.deadline[row] = self.ticks + 1
                        if self._estimable[self.provisional[row] | explanation]:
                            self.provisional[row] |= explanation
                        continue
                    self.confirmed[row] = True
                flagged = int(self.flagged[row])
                if (
                    waited < patience
                    and self.held[row] < 0
                    and not self.ambiguous[row]
                    and explanations.grown_by_chance(explanation, flagged | frozen, flagged, explained)
                ):
                    # a witness between the isolation and the detection levels grows it: wait a tick, the choice
                    # re-made on each until the patience ends, none held meanwhile (module docstring, "Chance joins")
                    self.rechoosing[row] = True
                    self.deadline[row] = self.ticks + 1
                    if self._estimable[self.provisional[row] | explanation]:
                        self.provisional[row] |= explanation
                    continue
                # a frozen sensor's decision, and one re-made on every tick of the patience, waits on the witnesses'
                # next ticks, not on a test a hold would protect (decisions N-31)
                holds = not (explanation & frozen or (self.rechoosing[row] and waited < patience))
                if self._doubtful(row, explanation, confirm[i], waited, patience, frozen):
                    self.deadline[row] = self.ticks + 1  # one more tick of evidence, distrusting what is suspected
                    self.held[row] = explanation if holds else -1
                    if self._estimable[self.provisional[row] | explanation]:
                        self.provisional[row] |= explanation
                    continue
                other = explanations.generator_alternative(explanation, explained, frozen)
                if other is not None:
                    if not decided[row] and waited < self.arbitration_ticks:
                        self.deadline[row] = self.ticks + 1  # wait for the arbitration, trusting neither
                        self.held[row] = explanation if holds else -1
                        both = self.provisional[row] | explanation | other
                        if self._estimable[both]:
                            self.provisional[row] = both
                        continue
                    if (self.arbiter.log_ratio[row] > 0.0) != bool(explanation & BITS[2]):
                        explanation = other
                explanation = self.rotor_pair.with_rotor(
                    row, explanation, isolate[i], self.observer_of_mask, frozen, bool(self.pair_disagreed[row])
                )
                self.flagged[row] = explanation
                self.deadline[row] = -1
                self.held[row] = -1
                self.provisional[row] = explanation
            elif start[row]:
                self.provisional[row] = explanation
            elif self._estimable[self.provisional[row] | explanation]:
                # suspicion only grows while the isolation is under way: an estimate that moved back and forth
                # between explanations would re-admit a sensor at every move
                self.provisional[row] |= explanation
        raised = self.flagged & ~before
        if raised.any():
            self.clearing.start(SENSORS_OF_MASK[raised])
        self._pending = bool((self.deadline >= 0).any())
        self._maybe_flagged = True

    def _fault_persists(self, row: int, waited: int) -> int:
        """The isolation's "no fault" outcome, on ``row`` ``waited`` ticks after its detection: whether the observer
        that detected it (the one leaving out the flagged sensors; the all-sensor one while nothing is flagged) is
        consistent again on the k = min(waited, window) ticks after the detection's, S_k = Σ χ²_j/ŝ²_j over them
        against the upper α_confirm/L quantile of a healthy residual's k-tick sum (``window_threshold``, the design
        autocovariance; L looks, k = max(isolation_delay, 1) … window). +1: S_k beyond it, the fault persists; −1:
        a whole window after the detection within it, no fault (a healthy observer gets that far with probability
        ≥ 1 − α_confirm, so a detection raised by noise alone ends in a flag with probability ≤ α_confirm);
        0: not yet a whole window, the decision waits a tick. The ticks the detection rested on are left out: they
        are the ones that crossed the detection level."""
        k = min(waited, self.s.window)
        j = int(self.observer_of_mask[self.flagged[row]])
        fresh = self._history[(self.ticks - 1 - np.arange(k)) % self.s.window, row, j].sum() if k else 0.0
        if k and fresh > self.h_fresh[j, k]:
            return 1
        return -1 if k >= self.s.window else 0

    def _restart(self, row: int) -> None:
        """Start ``row``'s isolation afresh on this tick, as a detection on this tick starts one: its deadline
        ``isolation_delay`` ahead, its "no fault" test asked again (``_fault_persists``), the explanation held none,
        the arbitration's sums restarted (from the onset's jump where the parity shows one). The suspicion
        (``provisional``) stays."""
        self.started[row] = self.ticks
        self.deadline[row] = self.ticks + self.s.isolation_delay
        self.confirmed[row] = False
        self.held[row] = -1
        self.rechoosing[row] = False
        self.pair_disagreed[row] = False
        rows = self._rows == row
        self.arbiter.reset(rows, rows & ((self.flagged & GENERATOR_BITS) == 0))

    def _doubtful(
        self,
        row: int,
        explanation: int,
        confirm: np.ndarray,
        waited: int = 0,
        patience: int = 1,
        frozen: int = 0,
    ) -> bool:
        """Whether the decision on an explanation chosen at the isolation level waits a tick (``waited`` ticks since
        the isolation started):

        * while ``waited`` < ``patience``, when a witness fails the laxer confirmation level
          ``isolation_confirm_alpha``: evidence of a further fault that has not yet grown enough to reject it;
        * while ``waited`` < the rotor-speed tests' patience, when the explanation names no rotor-speed sensor and
          their sequential test has not yet decided (``rotor_pair.verdict`` 0): a rotor-speed gain beside a
          generator-speed fault shows in the pair's difference from its first tick but in the UIOs only as their
          states drift, so that flagging before the test says "healthy" would name a part of the faulty set first,
          and joining before it says "biased" would name a healthy sensor. An explanation that names a ``frozen``
          sensor is decided on the tick the frozen test fires unless the one look at the pair
          (``rotor_pair.disagrees``) finds it disagreeing, on this or an earlier tick of the isolation; from then on
          the sequential test decides it as any other, so a healthy sensor joins only where both the look
          (α_iso) and the test's Ville-bounded level pass."""
        j = self.observer_of_mask[explanation]
        if j < 0 or self.ambiguous[row]:
            return False
        rotor_open = not explanation & ROTOR_BITS and waited < self.rotor_pair.patience
        if rotor_open and explanation & frozen:
            self.pair_disagreed[row] |= self.rotor_pair.disagrees(row)
            rotor_open = bool(self.pair_disagreed[row])
        if rotor_open and self.rotor_pair.verdict(row, explanation) == 0:
            return True
        return waited < patience and bool((self.witnesses[j] * confirm).max() > 1.0)

    @property
    def pending(self) -> bool:
        """Whether an isolation is under way on any row (``provisional`` holds its current explanation: sensors an
        estimator should not lean on before they are flagged)."""
        return self._pending

    def _clear(self, y: np.ndarray, x_hat: np.ndarray, frozen_mask: np.ndarray, skip: np.ndarray, torque_band) -> None:
        """Unflag sensor s where its CUSUM says healthy and the observer 'selected set + s' is consistent."""
        if self.spread.enabled:  # the exclusion residuals in units of the row's healthy noise scale (``adaptive``)
            noise = self.spread.scale[:, self._all_healthy, None]
            y, x_hat = y / noise, x_hat / noise
        ready = self.clearing.step(y, x_hat, self.flagged, SENSORS_OF_MASK[frozen_mask], torque_band)
        ready &= ~skip[:, None]
        if not ready.any():
            return
        recent = self._history[(self.ticks - 1 - np.arange(self.s.clear_window)) % self.s.window].sum(axis=0)
        for s in range(N_SPEED):
            bit = 1 << s
            rows = np.flatnonzero(ready[:, s])
            if len(rows) == 0:
                continue
            with_s = self.observer_of_mask[self.flagged[rows] & ~bit]
            rows, with_s = rows[with_s >= 0], with_s[with_s >= 0]
            done = rows[recent[rows, with_s] <= self.h_clear[with_s]]
            self.flagged[done] &= ~bit
