"""Residual tests for the benchmark's pitch sensors, pitch actuators and converter (faults 1–3, 6–8).

Seed 000's observer bank watches the speed sensors only. These three families of residuals cover the rest of
the benchmark's fault catalogue that a model can see; each residual is white Gaussian with a known variance
when the turbine is healthy, so each test's threshold follows from the false-alarm budget alone.

* **Pitch sensors** (faults 1–3). Parity of blade i's two sensors, p_i = (β_i,m1 − β_i,m2)/(√2 σ_β). Flagged
  when |p_i| or the window mean of p_i is too large. Isolation within the pair: a frozen reading, else the
  sensor farther from the other two blades' four sensors over the parity window (the blades share the collective
  reference; with the benchmark's pitch loop a faulty sensor drags its own blade only part of the way, so it stays
  the outlier). The flag drops when the speed sensors' clearing test (``clearing``), Page's CUSUM of "the pair
  agrees again" against "the fault persists at the size seen so far", reaches h = ln(1/α) from a false-clear
  budget, and the window mean is back under its clearing level: a gain fault's parity follows the pitch, and near
  the detection limit a plain clearing level drops and raises the flag as the pitch moves.
* **Pitch actuators** (faults 6–7; ``pitch_actuator``). With the benchmark's pitch loop, actuator i is driven by
  β_ref + n̄_i, n̄_i the mean noise of its two sensors, so its pair mean is m̄_i = G_i β_ref + (1 + G_i) n̄_i. The
  cross-blade residual e_i = m̄_i − ½(m̄_j + m̄_k) cancels what the three actuators share, and w_i = (1 + G)⁻¹ e_i is
  white (¾ σ_β²) plus the signature s_θ = (1 + G)⁻¹ (G_θ − G) β_ref of blade i's actuator θ. The test is the GLR
  between actuators within tolerance and actuators that lost bandwidth over a window of ``actuator_window`` ticks,
  its threshold from the false-alarm budget in closed form; the flag clears on the same evidence the other way.
  The residual assumes healthy pitch sensors (a sensor fault moves its blade through the pitch loop), so the test
  rests while any pitch sensor is flagged and for one window after.
* **Converter** (fault 8). r = τ_g,m − τ̂_g, with τ̂_g the first-order converter (α_gc) driven by the torque
  reference: white with σ_τ. An offset shows as a shift of r's mean; it is tested every tick by Page's two-sided
  CUSUMs designed for a few offsets (``converter_shifts``), their threshold h = ln(2K/α) from the false-alarm
  budget (Lorden's bound), so a large offset is flagged in a few ticks and a small one as soon as its evidence
  adds up; the flag drops by a clearing CUSUM of "the offset is gone" against "it persists at the size seen"
  (``_converter``, ``_converter_clearing``).

Adaptive thresholds (``adaptive``, ``adapt_time_s``): each test uses its residual's healthy spread ŝ learnt online
(the parity, the actuator residual's w² per blade, the converter's block sums) and its offset b̂ (a calibration
bias: within ±2 × 0.2 deg on a parity and on w, ±90 N m on τ_g,m): (p − b̂)/ŝ, (Σp/√W − b̂√W)/ŝ, the actuator GLR
with σ_w² = ¾ σ_β² ŝ² (ŝ² learnt about b̂; the GLR itself maximises the offset out), and z = (r − b̂)/(ŝ σ_τ) in
the converter's CUSUMs, against the design thresholds.

Fault 9 (drive-train efficiency) has no test: a gearbox that loses more torque looks, to an observer that
treats the rotor torque as unknown, exactly like a different aerodynamic torque (docs/turbine.md).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from service.plugins import AlgorithmOptionError
from service.turbine.adaptive import HealthySpread
from service.turbine.component_settings import ComponentSettings
from service.turbine.frozen import FrozenReadings
from service.turbine.pitch_actuator import FAULTS, TOLERANCE, SignatureBank, glr_threshold
from service.turbine.pitch_actuator import glr as actuator_glr
from wwcore.backend import fast_module
from wwcore.channels import SENSOR_INDEX, TARGET_INDEX, Component
from wwcore.lti import second_order_tf, zoh
from wwcore.planes import Planes, planes
from wwcore.quantiles import norm_isf
from wwcore.scenario.mismatch import SENSOR_BIAS_TOLERANCE
from wwcore.turbine_frames import TurbineFrame
from wwcore.turbine_params import TurbineParams

M1 = np.array([SENSOR_INDEX[f"beta_{i}_m1"] for i in (1, 2, 3)])
M2 = np.array([SENSOR_INDEX[f"beta_{i}_m2"] for i in (1, 2, 3)])
M12 = np.concatenate([M1, M2])
M1_TARGET = np.array([TARGET_INDEX[f"beta_{i}_m1"] for i in (1, 2, 3)])
M2_TARGET = np.array([TARGET_INDEX[f"beta_{i}_m2"] for i in (1, 2, 3)])
_ACTUATORS = (Component.PITCH_ACTUATOR_1, Component.PITCH_ACTUATOR_2, Component.PITCH_ACTUATOR_3)
ACTUATOR_TARGET = np.array([TARGET_INDEX[c.value] for c in _ACTUATORS])
CONVERTER_TARGET = TARGET_INDEX[Component.CONVERTER.value]
TAU_G_M = SENSOR_INDEX["tau_g_m"]
OTHERS = np.array([[1, 2], [0, 2], [0, 1]])


class _Window(Planes):
    """Running sum over the last ``size`` pushes of an (n, m) statistic: the ring of the pushes and their total, one
    block (``wwcore.planes``; ``sums[:-1]`` and ``sums[-1]``), which the compiled tick takes."""

    PLANES: ClassVar[dict[str, tuple]] = {"sums": (("ring", slice(None, -1)), ("total", -1))}

    def __init__(self, size: int, shape: tuple[int, ...]):
        self.size = size
        self.sums = np.zeros((size + 1, *shape))
        self.__dict__.update(planes(self.sums, self.PLANES["sums"]))
        self.count = 0

    def push(self, x: np.ndarray) -> np.ndarray:
        slot = self.count % self.size
        self.total += x - self.ring[slot]
        self.ring[slot] = x
        self.count += 1
        return self.total

    @property
    def full(self) -> bool:
        return self.count >= self.size


def actuator_whitener(p: TurbineParams) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of (1 + G_d)⁻¹ for the nominal pitch actuator G_d (zero-order hold), as a difference equation."""
    wn, zeta = p.pitch.omega_n, p.pitch.zeta
    phi, gamma = zoh(np.array([[0.0, 1.0], [-(wn**2), -2.0 * zeta * wn]]), np.array([[0.0], [wn**2]]), p.dt)
    num, den = second_order_tf(phi, gamma)
    return den / (den + num)[0], (den + num) / (den + num)[0]  # (1 + N/D)⁻¹ = D / (D + N)


CROSS_BLADE = np.array([[1.0, -0.5, -0.5], [-0.5, 1.0, -0.5], [-0.5, -0.5, 1.0]])
"""e = m̄ @ CROSS_BLADE: each blade's pair mean minus the mean of the other two blades' (symmetric)."""
SIGNATURE_KERNEL_ROWS = 12
"""Where ``fast_actuator.numpy_matmul_order`` finds none (a BLAS or CPU whose vector-matrix kernel the compiled
arithmetic does not reproduce), batches of at most this many rows compute the pitch-actuator signatures by
``fast_actuator.signature_block`` with BLAS calls, wider ones by numpy (the same numbers): the kernel makes one BLAS
call per row and candidate where numpy's stacked ``matmul`` makes them without leaving C, and was the slower above
12–16 rows (measured: 2 rows 60–100 µs per block against numpy's 130–250, 100 rows 2.9–3.3 ms against 2.4). Where it
finds one, every batch takes the kernel, with the products computed in it."""


class ComponentFDI(Planes):
    """Flags pitch sensors, pitch actuators and the converter for n turbines (DIAGNOSIS_TARGETS columns)."""

    PLANES: ClassVar[dict[str, tuple]] = {
        "_converter_cusums": ("converter_statistic", "_converter_run"),
        "_converter_sums": ("_converter_count", "_converter_mean", "converter_clear_statistic", "_converter_block_sum"),
    }

    def __init__(self, p: TurbineParams, n: int, sigma: dict[str, float], settings: ComponentSettings, fast=None):
        if settings.actuator_window % settings.block:
            raise AlgorithmOptionError(
                f"component_actuator_window ({settings.actuator_window}) must be a whole number of component_block "
                f"({settings.block}) ticks"
            )
        if not settings.converter_shifts or len(set(settings.converter_shifts)) < len(settings.converter_shifts):
            raise AlgorithmOptionError(
                f"component_converter_shifts {list(settings.converter_shifts)} must be one or more distinct offsets"
            )
        short = settings.actuator_clear_windows
        if any(m % settings.block or m >= settings.actuator_window for m in short) or len(set(short)) < len(short):
            raise AlgorithmOptionError(
                f"component_actuator_clear_windows {list(short)} must be distinct whole numbers of component_block "
                f"({settings.block}) ticks below component_actuator_window ({settings.actuator_window})"
            )
        self.s = settings
        self.n = n
        self._fast = fast  # ``service.turbine.fast`` (``wwcore.backend``) or None
        self._fast_actuator = fast_module("service.turbine.fast_actuator") if fast is not None else None
        self._fast_converter = fast_module("service.turbine.fast_converter") if fast is not None else None
        # the signature bank's state products: BLAS's arithmetic in the kernel where it equals numpy's on this machine
        self._matmul_order = self._fast_actuator.numpy_matmul_order() if fast is not None else 0
        self._compiled_signatures = fast is not None and (n <= SIGNATURE_KERNEL_ROWS or self._matmul_order != 0)
        alpha = settings.false_alarms_per_1000s * p.dt / 1000.0
        self.sigma_beta = sigma["beta_1_m1"]
        self.sigma_tau = sigma["tau_g_m"]
        # pitch-sensor parity: a two-sided single-tick test and a two-sided window-mean test, α/2 each, 3 blades
        self.z_single = norm_isf(alpha / 12.0)
        self.z_clear = norm_isf(settings.clear_alpha / 2.0)
        # the block tests decide once per block: their per-decision budget is a block's worth of ticks
        block_alpha = alpha * settings.block
        # the actuator GLR (``pitch_actuator``, eq. 4): raise against 3 blades × |F| candidates, clear against |T|
        self.h_actuator = glr_threshold(block_alpha, 3 * len(FAULTS))
        # clear against |T| on each of the clearing windows (the full one and the shorter ones): a union bound
        clear_block_alpha = settings.false_clears_per_1000s * p.dt * settings.block / 1000.0
        self.h_actuator_clear = glr_threshold(clear_block_alpha, len(TOLERANCE) * (1 + len(short)))
        # the converter's CUSUMs: 2 signs × the shifts share the row's per-tick budget α; Lorden: each one-sided
        # CUSUM on a log-likelihood ratio runs at least e^h ticks before a false alarm
        shifts = np.sort(np.asarray(settings.converter_shifts, dtype=float))
        self.converter_shifts = np.concatenate([shifts, shifts])  # (2K,): +m_j then −m_j
        self.converter_signs = np.concatenate([np.ones(len(shifts)), -np.ones(len(shifts))])
        self.h_converter = float(np.log(2.0 * len(shifts) / alpha))
        self._parity_scale = 1.0 / (np.sqrt(2.0) * self.sigma_beta)
        self._window_scale = 1.0 / np.sqrt(settings.parity_window)
        self._pitch_flagged = False  # whether any pitch-sensor flag is set (the healthy fast path needs none)
        self.parity = _Window(settings.parity_window, (n, 3))
        self.signatures = SignatureBank(p, *actuator_whitener(p), n)
        n_candidates = len(self.signatures.candidates)
        self.actuator = _Window(settings.actuator_window // settings.block, (n, 3, n_candidates))  # Σ w_i s_θ
        self.actuator_energy = _Window(settings.actuator_window // settings.block, (n, n_candidates))  # Σ s_θ²
        self.actuator_sums = _Window(settings.actuator_window // settings.block, (n, 3 + n_candidates))  # Σw, Σs
        self.actuator_glr = np.zeros((n, 3))  # Λ_i of the last decision (``pitch_actuator``, eq. 3)
        # the same three sums over each shorter clearing window
        self.actuator_short = [
            tuple(
                _Window(m // settings.block, shape)
                for shape in ((n, 3, n_candidates), (n, n_candidates), (n, 3 + n_candidates))
            )
            for m in sorted(short)  # shortest first: newer evidence outranks older (``_actuator``)
        ]
        # blocks until blade i's actuator test may raise again after its flag cleared: the raise window must first
        # hold no evidence from before the clearing
        self._actuator_cleared_rest = np.zeros((n, 3), dtype=np.int64)
        # Page's CUSUMs of the converter residual z (n, 2K), the clearing CUSUM's fault-size estimate μ̂, its tick
        # count and statistic C (n,), and the block's Σ r for the healthy spread (``adaptive``)
        # (the planes of two blocks, ``wwcore.planes``, which the compiled tick takes; the run: ticks since each CUSUM
        # was last zero)
        self._converter_cusums = np.zeros((len(self.PLANES["_converter_cusums"]), n, len(self.converter_shifts)))
        self._converter_sums = np.zeros((len(self.PLANES["_converter_sums"]), n))
        for block in self.PLANES:
            self.__dict__.update(planes(getattr(self, block), self.PLANES[block]))
        self._converter_weight = min(1.0, p.dt / settings.converter_memory_s)
        self.whiten_b, self.whiten_a = actuator_whitener(p)
        if len(self.whiten_b) != 3 or len(self.whiten_a) != 3:
            raise ValueError("the nominal pitch actuator should give a second-order whitening filter")
        self._w_state = (np.zeros((n, 3)), np.zeros((n, 3)))  # transposed direct form II
        self._e_block = np.zeros((settings.block, n, 3))
        self._w_block = np.empty((settings.block, n, 3))  # the whitened e of the block's ticks
        self._ref_block = np.zeros((settings.block, n))  # the frames' pitch references β_ref
        self._tau_block = np.zeros((settings.block, 2, n))  # τ_g,m[k], τ_g,r[k−1]
        self._tau_hat: np.ndarray | None = None
        self._converter_gain = float(np.exp(-p.alpha_gc * p.dt))
        self._actuator_rest = np.zeros(n, dtype=np.int64)  # blocks until the actuator test may flag again
        self.readings = FrozenReadings((n, 6), settings.frozen_ticks, fast=fast)  # [β_i,m1 | β_i,m2]
        # each pitch sensor's distance from the other two blades' sensors, summed over the parity window: which
        # sensor of a pair is the outlier, on the window's evidence rather than one tick's
        self.outlier = _Window(settings.parity_window, (n, 6))
        # the pitch-sensor flags' clearing CUSUM (``clearing``'s test on the parity): ticks since the flag, the
        # fault size μ̂ seen so far (parity σ), and the statistic S
        self._clear_h = float(np.log(1000.0 / (settings.false_clears_per_1000s * p.dt)))
        self._clear_weight = min(1.0, p.dt / settings.fault_memory_s)
        self._clear_count = np.zeros((n, 3))
        self._clear_mean = np.zeros((n, 3))
        self._clear_statistic = np.zeros((n, 3))
        self.flags = np.zeros((n, len(TARGET_INDEX)), dtype=bool)
        self.ticks = 0
        self.warmup_ticks = round(settings.warmup_s / p.dt)
        # adaptive thresholds (``adaptive``): the parity's offset is at most the two sensors' calibration
        # tolerances, in parity units; the converter residual's at most τ_g,m's (N m per tick)
        adapt, top = settings.adapt_time_s, settings.max_noise_scale
        parity_limit = 2.0 * SENSOR_BIAS_TOLERANCE["beta_1_m1"] * self._parity_scale
        self.parity_spread = HealthySpread((n, 3), p.dt, adapt, top, parity_limit, fast=fast)
        block_s = p.dt * settings.block
        # w's offset is at most the cross-blade combination of the pair means' biases, twice one sensor's tolerance
        actuator_limit = 2.0 * SENSOR_BIAS_TOLERANCE["beta_1_m1"]
        self.actuator_spread = HealthySpread((n, 3), block_s, adapt, top, actuator_limit, fast=fast)
        self.converter_spread = HealthySpread((n,), block_s, adapt, top, SENSOR_BIAS_TOLERANCE["tau_g_m"], fast=fast)
        self._root_parity_window = float(np.sqrt(settings.parity_window))
        # the converter kernel's constants and the spread it reads (``_converter``; arrays updated in place)
        self._converter_test = (
            self._converter_gain, 1.0 / self.sigma_tau, self.converter_shifts, self.converter_signs, self.h_converter,
            self._converter_weight, float(settings.converter_clear_floor), self._clear_h, CONVERTER_TARGET,
        )  # fmt: skip
        self._converter_spread_state = self.converter_spread.state  # its planes' block (``wwcore.planes``)
        self._converter_state = (self._converter_cusums, self._converter_sums)
        self._kept: dict | None = None  # the compiled tick's kernel arguments (``_tick_arguments``)

    def step(self, frame: TurbineFrame) -> np.ndarray:
        y = frame.sensors
        j = self.ticks % self.s.block
        self._ref_block[j] = frame.beta_ref
        if self._fast is not None:  # the lines below by one kernel (``fast.component_step``), then the decisions
            tick, kept = self.tick_inputs(j), self._kept["packed"]
            return self.ticked(
                j, *self._fast.component_step_kept(y, frame.tau_g_ref, tick, self.readings.previous, kept)
            )
        beta = y[:, M12]  # [β_i,m1 | β_i,m2], one gather
        m1, m2 = beta[:, :3], beta[:, 3:]
        self._pitch_sensors(beta, m1, m2)
        np.matmul(0.5 * (m1 + m2), CROSS_BLADE, out=self._e_block[j])
        self._tau_block[j, 0] = y[:, TAU_G_M]
        self._tau_block[j, 1] = frame.tau_g_ref
        self.ticks += 1
        self._converter(self._tau_block[j, 0], self._tau_block[j, 1])
        return self._block_end(j)

    def tick_inputs(self, j: int) -> tuple:
        """``fast.component_step_kept``'s ``tick`` for block slot ``j``: (j, the two windows' slots, which β buffer,
        first, warm); the kept arguments (``_kept``, ``"packed"`` the kernel's struct) built once."""
        if self._kept is None:
            self._tick_arguments()
        buffer = self.ticks % 2  # two β buffers: the frozen test keeps the last tick's (``previous``)
        w, o = self.parity, self.outlier
        return j, w.count % w.size, o.count % o.size, buffer, self.ticks == 0, self.ticks + 1 > self.warmup_ticks

    def ticked(self, j: int, any_suspicious: bool, repeated: bool) -> np.ndarray:
        """``step``'s lines after its kernel (``fast.component_step_kept`` on ``tick_inputs(j)``, its results
        ``any_suspicious``, ``repeated``): counts, frozen readings, pitch decisions, the block's end. The flags."""
        beta = self._kept["beta"][self.ticks % 2]
        self.parity.count += 1
        self.outlier.count += 1
        self.readings.push(beta, repeated)
        self._pitch_flags(*self._kept["normalised"], any_suspicious)
        self.ticks += 1
        return self._block_end(j)

    def settled(self, j: int) -> bool:
        """Whether a compiled tick at block slot ``j`` that finds nothing suspicious or repeated changes no flag
        (``ticked``): not the block's last tick, past the warm-up, no pitch sensor flagged, no frozen count running."""
        readings, warm = self.readings, self.ticks + 1 > self.warmup_ticks
        return j != self.s.block - 1 and warm and not (self._pitch_flagged or readings.counting or readings.ticks < 2)

    def _block_end(self, j: int) -> np.ndarray:
        """The block's tests at its last tick, the flags dropped through the warm-up; the flags."""
        if j == self.s.block - 1:
            self._actuators()
            self._converter_spread()
        if self.ticks <= self.warmup_ticks:
            self.flags[:] = False
            self._pitch_flagged = False
        return self.flags

    def _tick_arguments(self) -> tuple:
        """``step``'s compiled kernel arguments kept from tick to tick: the two β buffers, the blocks, the scales, the
        parity's outputs, the adaptation's and the converter's (outputs written and read within a tick; state
        arrays updated in place, never replaced), and all of them with the windows' sums as one ``Kept``
        (``"packed"``, ``fast.component_step_kept``'s)."""
        n, spread = self.n, self.parity_spread
        parity, window = np.empty((n, 3)), np.empty((n, 3))
        parity_n, window_n = (np.empty((n, 3)), np.empty((n, 3))) if spread.enabled else (parity, window)
        learning = (spread.min_weight, spread.max_scale2, spread.state)
        adapt = (spread.enabled, self.flags, M1_TARGET, M2_TARGET, self._root_parity_window, self.z_single, learning)
        self._tau_hat = np.empty(n)  # τ̂_g, set from the first tick's reading by the kernel
        self._kept = {
            "beta": (np.empty((n, 3 * 2)), np.empty((n, 3 * 2))),
            "blocks": (self._e_block, self._tau_block),
            "scales": (self._parity_scale, self._window_scale, self.z_single),
            "parity": (parity, window),
            "adapt": (*adapt, parity_n, window_n),
            "normalised": (parity_n, window_n),  # the parity's statistics in the learnt spread: the decisions read them
            "converter": (self._converter_spread_state, self._converter_test, self._converter_state),
        }
        k = self._kept  # ``component_step_kept``'s one argument for them all
        k["packed"] = self._fast.Kept((
            (M12, TAU_G_M, CROSS_BLADE), k["blocks"], (self.parity.sums, self.outlier.sums), k["scales"], k["beta"],
            k["parity"], k["adapt"], self._tau_hat, k["converter"],
        ))  # fmt: skip
        return self._kept

    # -- pitch sensors ------------------------------------------------------------------------------------------
    def _pitch_sensors(self, beta: np.ndarray, m1: np.ndarray, m2: np.ndarray) -> None:
        """beta = [m1 | m2] (n, 6), the readings of the blades' first and second pitch sensors."""
        self.readings.push(beta)
        parity = (m1 - m2) * self._parity_scale
        window = self.parity.push(parity) * self._window_scale
        self._push_outlier(m1, m2)
        self._pitch_flags(*self._adapt_parity(parity, window))

    def _push_outlier(self, m1: np.ndarray, m2: np.ndarray) -> None:
        """Each pitch sensor's distance from the mean of the other two blades' four sensors, into its window sum
        (``outlier``): which sensor of a pair is the outlier, on the window's evidence."""
        others = 0.25 * (m1[:, OTHERS].sum(axis=2) + m2[:, OTHERS].sum(axis=2))
        self.outlier.push(np.abs(np.concatenate([m1, m2], axis=1) - np.concatenate([others, others], axis=1)))

    def _adapt_parity(self, parity: np.ndarray, window: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool | None]:
        """(p − b̂)/ŝ and (Σ_W p/√W − b̂ √W)/ŝ per blade (``adaptive``), and learn b̂, ŝ² from blades with no flag
        whose parity passes both tests; whether any of the two exceeds the single-tick level (None: not known)."""
        spread = self.parity_spread
        if not spread.enabled:
            return parity, window, None
        if self._fast is not None:  # the lines below by one kernel
            parity_n, window_n = np.empty_like(parity), np.empty_like(window)
            learning = (spread.min_weight, spread.max_scale2, spread.state)
            any_suspicious = self._fast.adapt_parity(
                parity, window, self.flags, M1_TARGET, M2_TARGET, self._root_parity_window, self.z_single, learning,
                parity_n, window_n,
            )  # fmt: skip
            return parity_n, window_n, any_suspicious
        centred = parity - spread.offset
        parity_n = centred / spread.scale
        window_n = (window - spread.offset * self._root_parity_window) / spread.scale
        flagged = self.flags[:, M1_TARGET] | self.flags[:, M2_TARGET]
        healthy = ~flagged & (np.maximum(np.abs(parity_n), np.abs(window_n)) <= self.z_single)
        spread.update(centred * centred, healthy, parity)
        return parity_n, window_n, None

    def _pitch_flags(self, parity: np.ndarray, window: np.ndarray, any_suspicious: bool | None) -> None:
        """Raise and clear the pitch-sensor flags from the parity and its window mean (``any_suspicious``: whether
        any exceeds the single-tick level, None when not known)."""
        maybe_frozen = self.readings.counting or self.s.frozen_ticks < 2  # else nothing can be frozen
        if any_suspicious is False and not (maybe_frozen or self._pitch_flagged):
            return  # the healthy fast path, known without the array of suspicious blades
        suspicious = np.maximum(np.abs(parity), np.abs(window)) > self.z_single
        if not (maybe_frozen or self._pitch_flagged or suspicious.any()):
            return  # the healthy fast path: nothing suspicious, frozen or flagged
        frozen = self.readings.frozen
        pair_frozen = frozen[:, :3] | frozen[:, 3:]
        if not (self._pitch_flagged or suspicious.any() or pair_frozen.any()):
            return
        flagged_1, flagged_2 = self.flags[:, M1_TARGET], self.flags[:, M2_TARGET]
        fault = suspicious | pair_frozen
        new = fault & ~(flagged_1 | flagged_2)
        if new.any():
            # the sensor farther from the other two blades' sensors over the window (or a frozen one) is the
            # faulty one
            distance = self.outlier.total
            first = ((distance[:, :3] >= distance[:, 3:]) | frozen[:, :3]) & ~frozen[:, 3:]
            flagged_1 = flagged_1 | (new & first)
            flagged_2 = flagged_2 | (new & ~first)
        healthy = self._pitch_clearing(parity, flagged_1 | flagged_2, new) & (np.abs(window) < self.z_clear)
        healthy &= ~pair_frozen
        self.flags[:, M1_TARGET] = flagged_1 & ~healthy
        self.flags[:, M2_TARGET] = flagged_2 & ~healthy
        self._pitch_flagged = bool(self.flags[:, M1_TARGET].any() or self.flags[:, M2_TARGET].any())

    def _pitch_clearing(self, parity: np.ndarray, flagged: np.ndarray, raised: np.ndarray) -> np.ndarray:
        """Page's CUSUM of "the pair agrees again" against "the fault persists at the size seen so far" on the
        parity of each flagged pair (the speed sensors' test, ``clearing``): S ← max(0, S + m(m/2 − sgn(μ̂) p)),
        m = max(|μ̂|, ``clear_floor``), μ̂ the parity's running mean since the flag (exponentially weighted over
        ``fault_memory_s``); healthy once S ≥ h = ln(1/α) from ``false_clears_per_1000s``. While a gain fault's
        parity μ̂ ∝ β stays above the floor, S drifts down whatever the noise does, so a parity wandering about
        the clearing level no longer drops and raises the flag; (n, 3) bool where S ≥ h."""
        count, mean, statistic = self._clear_count, self._clear_mean, self._clear_statistic
        count[raised], mean[raised], statistic[raised] = 0.0, 0.0, 0.0
        count += flagged
        weight = np.where(flagged, np.maximum(1.0 / np.maximum(count, 1.0), self._clear_weight), 0.0)
        mean += weight * (parity - mean)
        m = np.maximum(np.abs(mean), self.s.clear_floor)
        llr = m * (0.5 * m - np.where(mean < 0.0, -parity, parity))
        statistic[:] = np.where(flagged, np.maximum(0.0, statistic + llr), 0.0)
        return flagged & (statistic >= self._clear_h)

    # -- pitch actuators (once per block) -----------------------------------------------------------------------
    def _actuators(self) -> None:
        # w = (1 + G)⁻¹ e, a normalised (a0 = 1) second-order section in transposed direct form II, tick by tick
        # The input products b_i e of all the block's ticks are taken at once; only the recursion runs per tick.
        (b0, b1, b2), (_, a1, a2) = self.whiten_b, self.whiten_a
        e, w = self._e_block, self._w_block
        if self._fast is not None:
            z2 = self._fast.whiten_block(e, b0, b1, b2, a1, a2, *self._w_state, w)  # the same, states in place
        else:
            b0e, b1e, b2e = b0 * e, b1 * e, b2 * e
            s1, s2 = self._w_state
            for k in range(len(e)):
                wk = np.add(b0e[k], s1, out=w[k])
                s1, s2 = b1e[k] - a1 * wk + s2, b2e[k] - a2 * wk
            self._w_state = (s1, s2)
            z2 = np.add.accumulate(w * w, axis=0)[-1]  # Σ_k w_k², added in tick order
        if self._compiled_signatures:  # the signatures and the block's sums below by one kernel
            block_correlation, block_energy, block_sums = self._fast_signatures(w)
            z1 = block_sums[:, :3].copy()
        else:
            z1 = w.sum(axis=0)  # Σ over the block of w (n, 3)
            s = self.signatures.block(self._ref_block)  # s_θ[k] (ticks, n, K), eq. 1
            block_correlation = np.einsum("knb,knc->nbc", w, s)
            block_energy = np.einsum("knc,knc->nc", s, s)
            block_sums = np.concatenate([z1, s.sum(axis=0)], axis=1)
        b = self.actuator_spread.offset  # w's learnt offset b̂ (``adaptive``), deg
        # Σ over the block of (w − b̂)², in units of its design variance
        z2 = (z2 - 2.0 * b * z1 + self.s.block * b * b) * (1.0 / (0.75 * self.sigma_beta**2))
        if self._fast is not None and self.actuator_short:  # the lines below by one kernel
            self._fast_actuator_test(z1, z2, block_correlation, block_energy, block_sums)
            return
        correlation = self.actuator.push(block_correlation)  # Σ_window w_i s_θ
        energy = self.actuator_energy.push(block_energy)  # Σ_window s_θ²
        sums = self.actuator_sums.push(block_sums)  # Σ w_i, Σ s_θ
        short_windows = [
            (c.push(block_correlation), e.push(block_energy), t.push(block_sums), c.size * self.s.block)
            for c, e, t in self.actuator_short
        ]
        count = self.s.block * min(self.actuator_sums.count, self.actuator_sums.size)
        sensor_flagged = self.flags[:, M1_TARGET].any(axis=1) | self.flags[:, M2_TARGET].any(axis=1)
        rest = self.actuator.size
        self._actuator_rest = np.where(sensor_flagged, rest, np.maximum(self._actuator_rest - 1, 0))
        spread = self.actuator_spread
        variance = (0.75 * self.sigma_beta**2) * spread.scale2  # σ_w² per blade (n, 3)
        centring = (sums[:, :3], sums[:, 3:], count)  # the window's offset of w maximised out (eq. 5)
        glr = actuator_glr(correlation, energy, variance, self.signatures.n_faults, centring)  # Λ_i
        self.actuator_glr = glr
        if spread.enabled:  # w²'s healthy scale ŝ² (``adaptive``), learnt while no blade is suspected
            quiet = ~self.flags[:, ACTUATOR_TARGET].any(axis=1) & (self._actuator_rest == 0)
            healthy = quiet & (glr <= self.h_actuator).all(axis=1) if self.actuator.full else quiet
            spread.update_rows(z2 * (1.0 / self.s.block), healthy, z1 * (1.0 / self.s.block))
        if not self.actuator.full:
            return
        # the blade with the largest Λ, as before any clearing: the other blades see −½ s_θ of a faulty one, so a
        # resting blade is not passed over for the next
        worst = np.argmax(glr, axis=1)
        resting = self._actuator_cleared_rest[np.arange(self.n), worst] > 0
        fault = (glr[np.arange(self.n), worst] > self.h_actuator) & (self._actuator_rest == 0) & ~resting
        flagged = self.flags[:, ACTUATOR_TARGET]
        flagged[np.flatnonzero(fault), worst[fault]] = True
        # the flag drops on a window's evidence for the tolerance against every fault (``pitch_actuator``): the
        # full window's, or a shorter one's, which holds only the pitch motion since a fault that ended; with the
        # pitch at rest there is none either way, and the flag stays. Newer evidence outranks older: a window
        # clears only if no shorter window favours a fault by the raise threshold (an actuator that changes
        # inside the full window, as on a ramp, is no fixed θ, and the full window may favour T while the last
        # second says F).
        clear = np.zeros_like(flagged)
        if flagged.any():  # the shorter windows' GLRs only decide clearings
            recent_fault = np.zeros_like(flagged)
            for correlation_m, energy_m, sums_m, count_m in short_windows:
                glr_m = actuator_glr(
                    correlation_m, energy_m, variance, self.signatures.n_faults, (sums_m[:, :3], sums_m[:, 3:], count_m)
                )
                clear |= (glr_m <= -self.h_actuator_clear) & ~recent_fault
                recent_fault |= glr_m > self.h_actuator
            clear |= (glr <= -self.h_actuator_clear) & ~recent_fault
        kept = flagged & ~clear & (self._actuator_rest == 0)[:, None]
        self._actuator_cleared_rest = np.where(flagged & ~kept, rest, np.maximum(self._actuator_cleared_rest - 1, 0))
        self.flags[:, ACTUATOR_TARGET] = kept

    def _fast_signatures(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The signatures of the block and its sums Σ w s_θ, Σ s_θ², [Σ w | Σ s_θ], by one kernel (the numpy lines
        of ``_actuators`` in their order: ``SignatureBank.block_sums``)."""
        kernel = self._fast_actuator.signature_block
        return self.signatures.block_sums(self._ref_block, w, kernel, self._matmul_order)

    def _fast_actuator_test(self, z1, z2, block_correlation, block_energy, block_sums) -> None:
        """``_actuators`` from the block's sums on, by ``service.turbine.fast_actuator.actuator_test`` (the same
        operations)."""
        full_windows = (self.actuator, self.actuator_energy, self.actuator_sums)
        short = [window for windows in self.actuator_short for window in windows]
        slots = np.array([w.count % w.size for w in (*full_windows, *short)], dtype=np.int64)
        for w in (*full_windows, *short):
            w.count += 1
        count = self.s.block * min(self.actuator_sums.count, self.actuator_sums.size)
        short_counts = np.array([c.size * self.s.block for c, _, _ in self.actuator_short], dtype=np.int64)
        windows = (block_correlation, block_energy, block_sums, *((w.ring, w.total) for w in full_windows))
        shorter = tuple(tuple(a for w in windows_m for a in (w.ring, w.total)) for windows_m in self.actuator_short)
        spread = self.actuator_spread
        thresholds = (self.s.block, 0.75 * self.sigma_beta**2, self.h_actuator, self.h_actuator_clear, count)
        thresholds += (short_counts, self.signatures.n_faults, self.actuator.full)
        self.actuator_glr = np.empty((self.n, 3))
        state = (self._actuator_rest, self._actuator_cleared_rest, self.actuator.size, self.actuator_glr)
        learning = (spread.enabled, spread.min_weight, spread.max_scale2, spread.state)
        targets = (ACTUATOR_TARGET, M1_TARGET, M2_TARGET)
        self._fast_actuator.actuator_test(
            z1, z2, windows, shorter, slots, thresholds, targets, state, learning, self.flags
        )

    # -- converter (every tick) ----------------------------------------------------------------------------------
    def _converter(self, tau_g_m: np.ndarray, tau_g_ref_previous: np.ndarray) -> None:
        """One tick of the converter test on r = τ_g,m[k] − τ̂_g[k], τ̂_g[k] = a τ̂_g[k−1] + (1 − a) τ_g,r[k−1]
        (the design model's first-order converter; τ̂_g starts at the first reading).

        z = (r − b̂)/(ŝ σ_τ) is white N(0, 1) on a healthy converter. Raise: Page's two-sided CUSUMs
        S_j^± ← max(0, S_j^± + m_j (±z − m_j/2)) for each shift m_j (``converter_shifts``), the log-likelihood
        ratio of N(±m_j, 1) against N(0, 1); flagged when any S ≥ h = ln(2K/α), α = rate·Ts/1000 per tick
        (Lorden: each of the 2K one-sided tests runs e^h ticks on average before a false alarm). An offset of
        d σ is found after about min_j h / (m_j (d − m_j/2)) ticks once τ_g has followed it (the converter's
        lag, 1/α_gc = 2 ticks); an offset below min m_j / 2 never is. Clear: ``_converter_clearing``."""
        a = self._converter_gain
        if self._fast_converter is not None:  # the lines below and ``_converter_clearing`` by one kernel
            first = self._tau_hat is None
            if first:
                self._tau_hat = np.empty_like(tau_g_m)
            self._fast_converter.converter_tick(
                tau_g_m, tau_g_ref_previous, self._tau_hat, first, self.ticks > self.warmup_ticks,
                self._converter_spread_state, self._converter_test, self.flags, self._converter_state,
            )  # fmt: skip
            return
        if self._tau_hat is None:
            self._tau_hat = tau_g_m.copy()
        else:
            self._tau_hat = a * self._tau_hat + (1.0 - a) * tau_g_ref_previous
        r = tau_g_m - self._tau_hat
        self._converter_block_sum += r
        if self.ticks <= self.warmup_ticks:
            return
        spread = self.converter_spread
        z = (r - spread.offset) * (1.0 / self.sigma_tau) / spread.scale
        flagged = self.flags[:, CONVERTER_TARGET]
        m = self.converter_shifts
        statistic = np.maximum(0.0, self.converter_statistic + m * (z[:, None] * self.converter_signs - 0.5 * m))
        statistic[flagged] = 0.0  # a flagged row's raise tests rest; they start from zero when it clears
        run = np.where(statistic > 0.0, self._converter_run + 1.0, 0.0)
        raised = (statistic >= self.h_converter).any(axis=1) & ~flagged
        if raised.any():
            # the clearing starts from the offset the CUSUM furthest over its threshold saw over its run of L ticks
            # since it was last zero: S = m Σ(±z − m/2) there, so ±z's mean is S/(m L) + m/2, taken as seen for L ticks
            rows = np.flatnonzero(raised)
            best = np.argmax(statistic[rows], axis=1)
            length = np.maximum(run[rows, best], 1.0)
            self._converter_mean[rows] = self.converter_signs[best] * (
                statistic[rows, best] / (m[best] * length) + 0.5 * m[best]
            )
            self._converter_count[rows] = length
            self.converter_clear_statistic[rows] = 0.0
            statistic[rows] = 0.0
            run[rows] = 0.0
        self.converter_statistic = statistic
        self._converter_run = run
        held = self._converter_clearing(z, flagged)
        self.flags[:, CONVERTER_TARGET] = raised | (flagged & ~held)

    def _converter_clearing(self, z: np.ndarray, flagged: np.ndarray) -> np.ndarray:
        """Page's CUSUM of "the converter is healthy again" against "the offset persists at the size seen so far"
        on the flagged rows (the pitch sensors' clearing, ``_pitch_clearing``): C ← max(0, C + m(m/2 − sgn(μ̂) z)),
        m = max(|μ̂|, ``converter_clear_floor``), μ̂ z's running mean since the flag (exponentially weighted over
        ``converter_memory_s``, started at the raising CUSUM's estimate, ±z's mean over its run since it was last
        zero, as if seen for the run's ticks: a start at the CUSUM's shift instead, which can be twice the offset,
        cleared a 1.1 σ offset's flag 0.25 s after it rose on the benchmark).
        While an offset d > m/2 persists, C drifts down (E = −m(d − m/2) per tick); once it is gone, up by m²/2
        per tick. Cleared where C ≥ h = ln(1/α) from ``false_clears_per_1000s``; (n,) bool."""
        count, mean = self._converter_count, self._converter_mean
        count += flagged
        weight = np.where(flagged, np.maximum(1.0 / np.maximum(count, 1.0), self._converter_weight), 0.0)
        mean += weight * (z - mean)
        m = np.maximum(np.abs(mean), self.s.converter_clear_floor)
        llr = m * (0.5 * m - np.where(mean < 0.0, -z, z))
        statistic = np.where(flagged, np.maximum(0.0, self.converter_clear_statistic + llr), 0.0)
        self.converter_clear_statistic = statistic
        return flagged & (statistic >= self._clear_h)

    def _converter_spread(self) -> None:
        """Learn the converter residual's healthy offset b̂ and spread ŝ² (``adaptive``) from the block's Σ r, on
        rows whose converter is not flagged."""
        r = self._converter_block_sum
        spread = self.converter_spread
        if spread.enabled:
            centred = r - self.s.block * spread.offset
            q = centred * centred * (1.0 / (self.s.block * self.sigma_tau**2))
            spread.update(q, ~self.flags[:, CONVERTER_TARGET], r * (1.0 / self.s.block))
        r[:] = 0.0
