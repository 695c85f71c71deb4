"""From an observer's state estimate to the rotor-effective wind speed, and the estimates sent to the controller.

1. Aerodynamic torque from the rotor equation (21) of seed 000 solved for τ_r, with the observer's estimates::

       τ̂_r = J_r dΩ̂/dt + K_dt θ̂_Δ + (B_dt + B_r) ω̂_r − (B_dt/N_g) ω̂_g

   The rotor acceleration is taken from Ω̂ = ω̂_g/N_g where the observer uses a generator-speed sensor: below
   the 4.5 Hz torsion mode the shaft is rigid (the low-frequency part of θ̇_Δ = ω_r − ω_g/N_g is ~1e-4 rad/s),
   and the generator encoder is ~50× less noisy than the rotor-speed sensors once referred to the rotor side.
   A UIO without one would use Ω̂ = ω̂_r; the bank has none. Observer 4 (``uio.design_rigid``: no θ̂_Δ) takes
   the two shaft equations summed instead, τ̂_r = (J_r/N_g + N_g J_g/η) dω̂_g/dt + (N_g/η)(τ̂_g + B_g ω̂_g) +
   B_r ω̂_g/N_g, exact but for the torsion's own 4.5 Hz motion. Observers 5 and 5-pe's Kalman designs have no
   generator encoder; their fifth state is τ̂_r.
2. τ̂_r and the pitch are low-pass filtered by second-order Butterworth filters (cutoff ``wind_cutoff_hz``), so
   both carry the same delay, except the torque of the observers on noisier speed channels than observer 4's
   (4-g1, 4-g2, 5), whose cutoff follows their noise (``torque_cutoffs``), then
3. v̂ solves τ̂_r = ½ρπR³ C_q(ω̂_r R / v, β̂) v² (``wwcore.aero.wind_from_torque``), started from the previous
   estimate (after a change of the estimate's observer, iterated on to the new torque's root: ``WindRecovery.wind``);
   the anemometer only provides the start value at the first tick. ω̂_r here is the published speed
   estimate (filtered at ``speed_cutoff_hz``): the rotor's inertia makes it change too slowly for the two
   filters' different delays to matter in λ.

The pitch is the mean over the blades of each blade's healthy pitch sensors (a blade whose two sensors are
both flagged falls back to the collective reference through the nominal actuator model). Measured rather than
modelled, because a faulty pitch sensor really moves its blade (the benchmark's pitch loop), and a faulty
actuator really lags. The published speed estimates pass through a second-order Butterworth filter
(``speed_cutoff_hz``) that removes the torsion mode, which is unobservable once the unknown input is decoupled
in observers without a generator-speed sensor; there ω̂_g = N_g ω̂_r. The generator speed sent to the controller
is that filtered ω̂_g except in region 2 from an observer with a generator-speed sensor, which sends its unfiltered
ω̂_g: there the filter's lag at the torsion mode turns the controller's torque law into a negative damper of the
shaft (``WindRecovery.region2_generator_speed``).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from service.turbine.bank import GENERATOR, ROTOR, SPARSE_PRODUCT_ROWS, BankDesign
from wwcore import aero
from wwcore.lti import biquad_steady_state, butter2_lowpass, zoh
from wwcore.turbine_params import TurbineParams

# The wind inversion (``aero.wind_from_torque``): warm-started from the previous estimate, 0.2 s apart, 3 iterations
# suffice; after a change of observer, as many as cross [1, 40] m/s in a flat branch's 20 % steps (log 40 / log 1.2
# = 20.2), so the estimate is the new observer's root whatever the old guess (``WindRecovery.wind``).
WARM_ITERATIONS = 3
SETTLE_ITERATIONS = 21
# A fresh inversion on the stalled branch (``WindRecovery.wind``'s ``stalled``) takes the root found from WIND_MAX
# where it lies above the guess's root by more than this (relative): a second root, not the same one's last digits.
DISTINCT_ROOT = 1e-6


class Biquad:
    """Second-order Butterworth low-passes (transposed direct form II) on the columns of (n, m) arrays; each
    column has its own cutoff (``cutoffs_hz``, length m)."""

    def __init__(self, cutoffs_hz: np.ndarray, dt: float):
        coeffs = [butter2_lowpass(fc, dt) for fc in cutoffs_hz]
        self.b = np.array([b for b, _ in coeffs]).T  # (3, m)
        if not np.allclose(self.b[1], 2.0 * self.b[0]) or not np.allclose(self.b[2], self.b[0]):
            raise ValueError("expected Butterworth low-pass numerators b0·[1, 2, 1]")
        self.a = np.array([a for _, a in coeffs]).T
        self.zi = np.array([biquad_steady_state(b, a) for b, a in coeffs]).T  # (2, m)
        self._b0, self._a1, self._a2 = self.b[0], self.a[1], self.a[2]  # rows used every call
        self.s1: np.ndarray | None = None
        self.s2: np.ndarray | None = None

    def start(self, x0: np.ndarray) -> None:
        """Set the state to the steady state of a constant input x0."""
        self.s1, self.s2 = self.zi[0] * x0, self.zi[1] * x0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        # A Butterworth low-pass has b = b0·[1, 2, 1]: one product of x serves all three taps. The states are
        # updated in place (same operations as s1 ← (2 bx + s2) − a1 y, s2 ← bx − a2 y, fewer temporaries).
        bx = self._b0 * x
        y = bx + self.s1
        s1, s2 = self.s1, self.s2
        twice = bx + bx
        twice += s2
        np.subtract(twice, np.multiply(self._a1, y, out=s1), out=s1)
        np.subtract(bx, np.multiply(self._a2, y, out=s2), out=s2)
        return y


def speed_noise_variance(observer, gear_ratio: float) -> float:
    """Variance (rad/s)² of the best linear unbiased estimate of ω_g from one tick of ``observer``'s speed channels
    alone, the r of the rigid drive train's Kalman filter on them: 1/(cᵀ R⁻¹ c), c_i = 1/N_g for a rotor-speed
    channel and 1 for a generator-side one (a generator-speed sensor, the power-speed channel). For a rigid observer
    it is its ω̂_g's variance (``state_error_cov[1, 1]``): σ_g²/2 for observer 4, N_g² σ_r²/2 for observer 5."""
    refer = np.where(observer.C[:, 0] > 0, 1.0 / gear_ratio, 1.0)
    return float(1.0 / (refer @ np.linalg.solve(observer.R, refer)))


def torque_cutoffs(bank: BankDesign, wind_cutoff_hz: float) -> np.ndarray:
    """Cutoff (Hz) of the wind filter on each observer's τ̂_r (n_obs,): ``wind_cutoff_hz``, scaled by (r_4 / r_j)^(1/4)
    for the observers whose speed channels are noisier than observer 4's (r_j: ``speed_noise_variance``) and that the
    estimate uses where the torque estimate's noise is what its error is made of: ``4-g1`` and ``4-g2`` (one
    generator-speed sensor: 2^(−1/4), 0.252 Hz of 0.3) and observer 5 (the rotor-speed sensors, r_5/r_4 = N_g² σ_r² /
    σ_g² = 2 280: 0.0434 Hz), which the estimate uses with both generator-speed sensors flagged below
    ``POWER_SPEED_MIN_TORQUE`` (region 1, ``builtin.UIOBankEstimator``) or at every torque with ``power_speed = false``.

    A rigid observer's τ̂_r is J_eq dω̂_g/dt through the filter (``uio.design_rigid``), and with the aerodynamic
    torque a random walk (the bank's model of it, ``DESIGN_Q_UNKNOWN``) that is the steady-state Kalman filter of
    the rigid drive train: a second-order Butterworth on ω̂_g whose bandwidth is (q / (J_eq² r Ts²))^(1/4) for
    speed variance r, differentiated. The filter's error is the sensors' noise, variance ∝ r f_c³ (white noise
    differentiated, then low-passed), plus its lag on the torque, variance ∝ q / f_c. The design's f_c is set for
    observer 4 (two encoders, r_4 = σ_g²/2); on channels of variance r_j, f_c (r_4/r_j)^(1/4) scales both terms by
    the same (r_j/r_4)^(1/4): the estimate then stands to its own optimum exactly as observer 4 stands to its own,
    whatever the wind makes q, and its torque error is (r_j/r_4)^(1/8) × observer 4's: 2^(1/8) = 1.09 on one encoder,
    2 280^(1/8) = 2.63 on the rotor-speed sensors. Kept at f_c, the noise term alone grows r_j/r_4-fold: √2 × on one
    encoder and up to 48 × on the rotor-speed sensors where the noise dominates (region 1, where a torque error moves
    the wind estimate most, ``docs/turbine.md``). Observer 5's Kalman τ̂_r has its own bandwidth, 0.156 Hz for its
    random walk (the same law with its q), 3.6 × above 0.0434 Hz: the cascade passes 0.83 × the noise (σ) of the
    Butterworth alone on J_eq dω̂_g/dt, at a little more lag. The 5-pe designs and every other observer keep
    ``wind_cutoff_hz``: where 5-pe serves (the power-speed channel live, region 2 from about 5 m/s, region 3) the
    twin's error is mostly what no torque filter touches, and the law's cutoffs (0.056–0.083 Hz) cost more lag than
    they saved noise (docs/turbine.md, "Estimates").
    """
    cutoffs = np.full(len(bank.observers), float(wind_cutoff_hz))
    reference = bank.observers[bank.index(frozenset(ROTOR))]  # observer 4: every generator-speed sensor
    if reference.kind != "rigid":
        return cutoffs
    reference_variance = speed_noise_variance(reference, bank.gear_ratio)
    scaled = [j for j, o in enumerate(bank.observers) if o.kind == "rigid" and set(o.sensors) <= set(GENERATOR)]
    rotor_only = bank.observers[bank.index(frozenset(GENERATOR))]  # observer 5: every rotor-speed sensor
    if rotor_only.kind == "kalman":
        scaled.append(bank.index(frozenset(GENERATOR)))
    for j in scaled:
        cutoffs[j] *= (reference_variance / speed_noise_variance(bank.observers[j], bank.gear_ratio)) ** 0.25
    return cutoffs


class PitchModel:
    """The nominal pitch actuator ω_n²/(s² + 2ζω_n s + ω_n²), discretised (zoh), driven by β_ref."""

    def __init__(self, p: TurbineParams, n: int):
        wn, zeta = p.pitch.omega_n, p.pitch.zeta
        A = np.array([[0.0, 1.0], [-(wn**2), -2.0 * zeta * wn]])
        B = np.array([[0.0], [wn**2]])
        Ad, Bd = zoh(A, B, p.dt)
        self.Ad, self.Bd = Ad, Bd.ravel()
        # the six coefficients as Python floats (the same doubles; unpacking the arrays every tick costs more)
        self._coef = (*(float(v) for v in Ad.ravel()), *(float(v) for v in self.Bd))
        self._coef_array = np.array(self._coef)
        self.x = (np.zeros(n), np.zeros(n))  # (β, β̇)

    def start(self, beta: np.ndarray) -> None:
        self.x = (beta.astype(float).copy(), np.zeros_like(beta, dtype=float))

    def step(self, beta_ref_prev: np.ndarray) -> np.ndarray:
        a, b, c, d, g0, g1 = self._coef
        beta, rate = self.x
        self.x = (a * beta + b * rate + g0 * beta_ref_prev, c * beta + d * rate + g1 * beta_ref_prev)
        return self.x[0]


class WindRecovery:
    """Torque, wind and filtered speeds for every observer of the bank, every tick (columns = observers).

    One matrix product maps [x̂[n], x̂[n−1]] to the raw columns [τ̂_r | ω̂_r | ω̂_g] of every observer; one bank
    of biquads filters them (τ̂_r and the pitch at ``wind_cutoff_hz``, the speeds at ``speed_cutoff_hz``).
    """

    def __init__(
        self, p: TurbineParams, bank: BankDesign, n: int, wind_cutoff_hz: float, speed_cutoff_hz: float, fast=None
    ):
        self.p = p
        self._fast = fast  # ``service.turbine.fast`` (``wwcore.backend``) or None
        self.n = n
        m = len(bank.names)
        width = bank.F_blk.shape[0]
        now = np.zeros((width, 3 * m))  # raw[n] = x̂[n] @ now + x̂[n−1] @ prev
        prev = np.zeros((width, 3 * m))
        torque, speed_r, speed_g = (slice(i * m, (i + 1) * m) for i in range(3))
        rigid = []  # (observer, column of its τ̂_g in x̂) of the rigid observers, whose τ̂_r uses τ̂_g
        encoder_speed = np.full(m, -1, dtype=np.int64)  # column of ω̂_g in x̂ where the observer has an encoder
        for j, o in enumerate(bank.observers):
            i0 = bank.offsets[j]
            uses_generator = any(s.startswith("omega_g") for s in o.sensors)
            encoder = any(s in GENERATOR for s in o.sensors)  # a generator-speed sensor, not the power-speed channel
            if encoder:
                encoder_speed[j] = i0 + 1
            col = torque.start + j
            if o.kind == "kalman" and not encoder:  # τ_r from the filter's fifth state (observers 5 and 5-pe)
                now[i0 + 4, col] = 1.0
            elif o.kind == "rigid":  # the two shaft equations summed (``uio.design_rigid``)
                inertia = (p.J_r / p.N_g + p.N_g * p.J_g / p.eta_dt) / p.dt
                now[i0 + 1, col] += inertia + p.N_g * p.B_g / p.eta_dt + p.B_r / p.N_g
                prev[i0 + 1, col] -= inertia
                now[i0 + 3, col] += p.N_g / p.eta_dt
                rigid.append((j, i0 + 3))
            else:
                accel_col, accel_gain = (i0 + 1, p.J_r / (p.N_g * p.dt)) if uses_generator else (i0, p.J_r / p.dt)
                now[accel_col, col] += accel_gain
                prev[accel_col, col] -= accel_gain
                now[i0 + 2, col] += p.K_dt
                now[i0 + 0, col] += p.B_dt + p.B_r
                now[i0 + 1, col] -= p.B_dt / p.N_g
            now[i0, speed_r.start + j] = 1.0
            if uses_generator:
                now[i0 + 1, speed_g.start + j] = 1.0
            else:
                now[i0, speed_g.start + j] = p.N_g
        self._map = np.vstack([now, prev])
        self._encoder_speed_state = encoder_speed
        self._rigid_torque_columns = np.array([j for j, _ in rigid], dtype=np.int64)
        self._rigid_converter_states = np.array([c for _, c in rigid], dtype=np.int64)
        self._converter_gain = p.N_g / p.eta_dt
        self._groups = (torque, speed_r, speed_g)
        self.torque_cutoffs_hz = torque_cutoffs(bank, wind_cutoff_hz)
        cutoffs = np.r_[self.torque_cutoffs_hz, np.full(2 * m, speed_cutoff_hz), wind_cutoff_hz]
        self.filter = Biquad(cutoffs, p.dt)  # columns: τ, ω_r, ω_g, β
        self.pitch = PitchModel(p, n)
        self.n_obs = m
        self._x_prev: np.ndarray | None = None
        self._filtered = np.zeros((n, 3 * m + 1))
        # [x̂[n], x̂[n−1]] and [raw, β], the inputs of the map and the filter, refilled in place every tick
        self._width = width
        self._stacked = np.empty((n, 2 * width))
        self._filter_in = np.empty((n, 3 * m + 1))
        self._no_columns = np.empty((n, 0))  # the empty middle block of ``fast.stack``
        self._map_nonzeros = self._sparse_map(fast, n)
        self._healthy_arguments = None  # ``step_healthy``'s kept arguments (``_healthy_kept``)
        self._healthy_speeds: tuple[np.ndarray, np.ndarray] | None = None  # its (ω̂_r, ω̂_g), written in place

    def _sparse_map(self, fast, n: int) -> tuple | None:
        """The map as its nonzeros for ``fast.gemm_product`` where ``fast.gemm_layout`` finds BLAS's arithmetic for
        its shape and ``n`` rows (``bank.SPARSE_PRODUCT_ROWS`` or more); else None: BLAS's product (fewer rows, the
        numpy backend, another BLAS or CPU). The map is about 1 % nonzero (a handful of physical coefficients per
        observer), so the product over its nonzeros is a small fraction of BLAS's dense work, with the same numbers."""
        if fast is None or n < SPARSE_PRODUCT_ROWS:
            return None
        lanes_from = fast.gemm_layout(n, *self._map.shape)
        return None if lanes_from is None else fast.nonzeros(self._map, lanes_from)

    def _mapped(self, stacked: np.ndarray) -> np.ndarray:
        """raw = [x̂[n], x̂[n−1]] @ map (n, 3 n_obs): by ``fast.gemm_product`` over the map's nonzeros where
        ``_sparse_map`` found it numpy's, else numpy's product."""
        if self._map_nonzeros is None:
            return stacked @ self._map
        raw = np.empty((self.n, self._map.shape[1]))
        self._fast.gemm_product(stacked, self._map, self._map_nonzeros, raw)
        return raw

    @property
    def filtered(self) -> np.ndarray:
        """(n, 3 n_obs + 1) the filtered columns [τ̂_r | ω̂_r | ω̂_g | β̄] (no copy)."""
        return self._filtered

    @property
    def speed_starts(self) -> tuple[int, int]:
        """The first column of ω̂_r and of ω̂_g in ``filtered``."""
        return self._groups[1].start, self._groups[2].start

    @property
    def omega_r(self) -> np.ndarray:
        """(n, n_obs) filtered rotor-speed estimates, rad/s."""
        return self._filtered[:, self._groups[1]]

    @property
    def omega_g(self) -> np.ndarray:
        """(n, n_obs) filtered generator-speed estimates, rad/s."""
        return self._filtered[:, self._groups[2]]

    @property
    def pitch_filtered(self) -> np.ndarray:
        return self._filtered[:, -1]

    def start(self, x_hat: np.ndarray, beta0: np.ndarray, tau_aero0: np.ndarray) -> None:
        self.pitch.start(beta0)
        raw = np.concatenate([x_hat, x_hat], axis=1) @ self._map
        raw[:, self._groups[0]] = tau_aero0[:, None]
        self.filter.start(np.column_stack([raw, beta0]))
        self._filtered = np.column_stack([raw, beta0])
        self._x_prev = x_hat
        self._healthy_arguments = None  # the filters' states, the pitch model's and ``_filtered`` are new arrays

    def transfer(
        self, rows: np.ndarray, target: np.ndarray, source: np.ndarray, bank: BankDesign, x_hat: np.ndarray
    ) -> None:
        """Observer ``target[i]`` of row ``rows[i]`` takes over observer ``source[i]``'s filtered torque and speeds
        and its change over this tick (x̂ the bank's estimates of this tick, after ``ObserverBank.restart``): its
        columns then go on as the source's would have, without the history it had before."""
        zi = self.filter.zi
        for group in self._groups:
            t_col, s_col = group.start + target, group.start + source
            for state in (self.filter.s1, self.filter.s2, self._filtered):
                state[rows, t_col] = state[rows, s_col]
            # A state means the same output only under the same coefficients: where the two columns' cutoffs
            # differ (``torque_cutoffs``), the target's rest state for the source's output replaces the source's
            # (s = zi y at rest, unit DC gain), so the target starts from the source's output and its departure
            # from rest, not from a state its own coefficients read as another output.
            output = self._filtered[rows, t_col]
            self.filter.s1[rows, t_col] += (zi[0, t_col] - zi[0, s_col]) * output
            self.filter.s2[rows, t_col] += (zi[1, t_col] - zi[1, s_col]) * output
        for row, t, s in zip(rows, target, source, strict=True):
            width = min(bank.observers[t].n_states, bank.observers[s].n_states)
            tb = slice(bank.offsets[t], bank.offsets[t] + width)
            sb = slice(bank.offsets[s], bank.offsets[s] + width)
            # x̂_T[n−1] such that the target's change over this tick is the source's (no step, hence no torque
            # impulse, where the two estimates differ)
            self._x_prev[row, tb] = x_hat[row, tb] - (x_hat[row, sb] - self._x_prev[row, sb])

    def step(
        self,
        x_hat: np.ndarray,
        beta_ref_prev: np.ndarray,
        pitch_m1: np.ndarray,
        pitch_m2: np.ndarray,
        healthy_m1: np.ndarray | None,
        healthy_m2: np.ndarray | None,
        measured_torque: np.ndarray | None = None,
    ) -> None:
        """Update torque, speed and pitch estimates of every observer from the bank's x̂[n] and the pitch
        sensors (n, 3 blades each) with their health flags (None and None: every pitch sensor is healthy).

        ``measured_torque`` (n,), NaN on the rows whose converter is trusted (None: all are): where given, the
        rigid observers' τ̂_r takes the generator torque from it (τ_g,m, N m) instead of their τ̂_g, which the
        design model drives with the torque reference and which misses a converter's offset
        (``converter_correction``)."""
        width, stacked = self._width, self._stacked
        if self._fast is not None:
            self._fast.stack(x_hat, self._no_columns, self._x_prev, stacked)
        else:
            stacked[:, :width] = x_hat
            stacked[:, width:] = self._x_prev
        raw = self._mapped(stacked)
        if measured_torque is not None:
            self.converter_correction(raw, x_hat, measured_torque)
        if self._fast is not None:  # the lines below by one kernel, the pitch model's state and ``_filtered`` in place
            f, pitch = self.filter, self.pitch
            healthy = None if healthy_m1 is None and healthy_m2 is None else (healthy_m1, healthy_m2)
            self._fast.recovery_tick(
                raw, pitch_m1, pitch_m2, healthy, pitch.x, np.ascontiguousarray(beta_ref_prev, dtype=float),
                pitch._coef_array, (f._b0, f._a1, f._a2, f.s1, f.s2), self._filtered,
            )  # fmt: skip
            self._x_prev = x_hat
            return
        modelled = self.pitch.step(beta_ref_prev)
        if healthy_m1 is None and healthy_m2 is None:
            # both sensors of every blade: the weighted mean below with weights 1, 1 (the same operations)
            per_blade = (pitch_m1 + pitch_m2) / 2.0
        else:
            weight = healthy_m1.astype(float) + healthy_m2
            per_blade = np.where(
                weight > 0,
                (healthy_m1 * pitch_m1 + healthy_m2 * pitch_m2) / np.maximum(weight, 1.0),
                modelled[:, None],
            )
        filter_in = self._filter_in
        filter_in[:, :-1] = raw
        filter_in[:, -1] = ((per_blade[:, 0] + per_blade[:, 1]) + per_blade[:, 2]) / 3.0  # β, mean(axis=1)'s sum
        self._filtered = self.filter(filter_in)
        self._x_prev = x_hat

    def step_healthy(
        self,
        faulty: np.ndarray,
        x_hat: np.ndarray,
        beta_ref_prev: np.ndarray,
        sensors: np.ndarray,
        pitch_columns: np.ndarray,
        selected: np.ndarray,
        zone: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """``step`` with every pitch sensor healthy and no converter correction, then each row's filtered ω̂_r and
        ω̂_g of observer ``selected``, ω̂_g already ``region2_generator_speed``'s for the controller's ``zone``, on
        the compiled backend only, by one kernel call (``fast.recovery_healthy_tick``: the same operations as
        ``_mapped``, ``step``, the estimator's gather and ``region2_generator_speed``). The pitch readings are
        gathered from ``sensors`` (columns ``pitch_columns``: β_i,m1 then β_i,m2). None, with nothing done, where
        any of ``faulty`` (the estimator's distrusted targets) is set; else (ω̂_r, ω̂_g) (n,) each, kept arrays that
        the next call overwrites: whoever keeps them past the tick copies them."""
        kept = self._healthy_arguments
        if kept is None:
            kept = self._healthy_arguments = self._healthy_kept()
        beta_ref_prev = np.ascontiguousarray(beta_ref_prev, dtype=float)
        if not self._fast.recovery_healthy_tick(
            faulty, x_hat, self._x_prev, sensors, beta_ref_prev, zone, pitch_columns, selected, kept
        ):
            return None
        self._x_prev = x_hat  # = ``healthy_ticked``, inline: the common tick's calls are counted
        return self._healthy_speeds

    def healthy_ticked(self, x_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``step_healthy``'s lines after its kernel found nothing distrusted, where a caller's kernel made the same
        call (``fast_supervisor``): x̂[n] kept as the next tick's x̂[n−1]; (ω̂_r, ω̂_g), the kept arrays."""
        self._x_prev = x_hat
        return self._healthy_speeds

    def healthy_kept(self):
        """``step_healthy``'s kept arguments (``_healthy_kept``), built on the first call after ``start``."""
        if self._healthy_arguments is None:
            self._healthy_arguments = self._healthy_kept()
        return self._healthy_arguments

    def _healthy_kept(self):
        """``step_healthy``'s kept arguments as one ``wwcore.kept.Kept`` (one struct for the kernel to unbox),
        arrays written in place and replaced only by ``start``: (([x̂[n], x̂[n−1]], map, its nonzeros or None, raw),
        the pitch model's (β, β̇), its coefficients, the biquads' (b0, a1, a2, s1, s2), ``_filtered``, (the first
        ω̂_r and ω̂_g column, ω̂_r and ω̂_g out), the map's ω̂_g state of each observer)."""
        f, n = self.filter, self.n
        self._healthy_speeds = (np.empty(n), np.empty(n))
        raw = np.empty((n, self._map.shape[1]))
        return self._fast.Kept((
            (self._stacked, self._map, self._map_nonzeros, raw),
            self.pitch.x,
            self.pitch._coef_array,
            (f._b0, f._a1, f._a2, f.s1, f.s2),
            self._filtered,
            (self._groups[1].start, self._groups[2].start, *self._healthy_speeds),
            self._encoder_speed_state,
        ))  # fmt: skip

    def region2_generator_speed(
        self, x_hat: np.ndarray, selected: np.ndarray, zone: np.ndarray, omega_g: np.ndarray
    ) -> np.ndarray:
        """The generator speed to send the controller: ``omega_g`` (n,), the selected observers' low-passed ω̂_g,
        replaced by their unfiltered ω̂_g (x̂'s column) on the rows in region 2 (``zone`` 0, the controller's zone
        of the last tick) whose observer ``selected`` has a generator-speed sensor.

        Why (docs/turbine.md, "The speed sent to the controller"): the controller's law sets τ_g,r from this speed,
        and the generator torque then acts on the drive train's 4.5 Hz torsion mode, which moves mostly the
        generator, like a damper of coefficient Re{g H(jω_t) C(jω_t) e^(−jω_t T_s)}: g = ∂τ_g,r/∂ω_g, H the
        speed's filter, C the converter. In region 2 g = 2 K_opt ω_g > 0 and the low-pass's 142 deg of lag at
        4.5 Hz (2 Hz cutoff), with the converter's 30 deg and the tick's 16 deg, turn that damper negative: from
        ω_g ≈ 120 rad/s up it outweighs the generator friction (the mode's ζ 0.0019 → −0.0006 at 150 rad/s) and the
        shaft rings up over minutes. Unfiltered, as the benchmark controller reads its own sensor, the mode's ζ is
        0.006–0.011 in region 2. In region 3 g = −P_r/(η_gc ω_g²) < 0 and the low-pass's lag is what makes the
        damper positive (ζ 0.003–0.009 against −0.002…−0.02 unfiltered), so the filtered speed stays there. An
        observer without a generator-speed sensor (5, 5-pe) does not see the generator side of the mode; its
        filtered ω̂_g stays in both regions.

        On the compiled backend ``omega_g`` (a fresh array of the caller's) is changed in place and returned
        (``fast.region2_speed``: the same values)."""
        if self._fast is not None:
            self._fast.region2_speed(x_hat, selected, zone, self._encoder_speed_state, omega_g)
            return omega_g
        state = self._encoder_speed_state[np.maximum(selected, 0)]
        unfiltered = (zone == 0) & (selected >= 0) & (state >= 0)
        if not unfiltered.any():
            return omega_g
        rows = np.flatnonzero(unfiltered)
        out = omega_g.copy()
        out[rows] = x_hat[rows, state[rows]]
        return out

    def converter_correction(self, raw: np.ndarray, x_hat: np.ndarray, measured_torque: np.ndarray) -> None:
        """Add (N_g/η_dt)(τ_g,m − τ̂_g) to the rigid observers' raw τ̂_r on the rows where ``measured_torque`` is
        not NaN, in place: their τ̂_r = … + (N_g/η_dt) τ̂_g then uses the measured generator torque. A converter
        offset Δ is added to the torque reference, so the generator really carries τ_g = τ̂_g + Δ (after the
        converter's lag) and τ_g,m reads it; τ̂_g, driven by the reference alone, misses Δ, and τ̂_r would carry
        (N_g/η_dt) Δ (95 × Δ: 43 kN m for a 5 σ offset)."""
        rows = np.flatnonzero(~np.isnan(measured_torque))
        if not len(rows) or not len(self._rigid_torque_columns):
            return
        states = x_hat[np.ix_(rows, self._rigid_converter_states)]
        raw[np.ix_(rows, self._rigid_torque_columns)] += self._converter_gain * (measured_torque[rows, None] - states)

    def rigid_speed_coefficients(self, bank: BankDesign, observer: int) -> tuple[float, float]:
        """c_now, c_prev (N m per rad/s): a rigid observer's raw τ̂_r = c_now ω̂_g[n] + c_prev ω̂_g[n−1] + terms in
        its τ̂_g (the map's coefficients of its ω̂_g state)."""
        if bank.observers[observer].kind != "rigid":
            raise ValueError("not a rigid observer")
        state, column = bank.offsets[observer] + 1, self._groups[0].start + observer
        return float(self._map[state, column]), float(self._map[self._width + state, column])

    def pair_difference_sigma(self, bank: BankDesign, pair: tuple[int, int]) -> float:
        """σ (N m) of the difference of two observers' filtered τ̂_r, each on one generator-speed sensor (``pair``:
        4-g1 and 4-g2), on a healthy plant.

        A rigid observer on one encoder has x̂ = that encoder's reading (its ω̂_g column) and τ̂_g from the torque
        reference alone (``uio.design_rigid``), so its raw τ̂_r is c_now y[n] + c_prev y[n−1] plus terms the two share
        (the converter's τ̂_g): the difference of the two raw torques is c_now e[n] + c_prev e[n−1] with e = y_1 − y_2,
        white of variance σ_1² + σ_2² (the design's R) whatever the wind, the aerodynamic torque and the drive train's
        motion, which both encoders read alike. Through the two columns' common Butterworth (their cutoffs are equal,
        ``torque_cutoffs``): variance (σ_1² + σ_2²) Σ_k g_k², g the impulse response of that filter on
        c_now + c_prev z⁻¹, summed until it has decayed (40 time constants of the cutoff)."""
        first, second = (bank.observers[j] for j in pair)
        if first.kind != "rigid" or second.kind != "rigid" or len(first.sensors) != 1 or len(second.sensors) != 1:
            raise ValueError("the pair must be two rigid observers on one generator-speed sensor each")
        cutoff = self.torque_cutoffs_hz[pair[0]]
        if not np.isclose(cutoff, self.torque_cutoffs_hz[pair[1]]):
            raise ValueError("the pair's torque filters differ: their difference is not the encoders' noise alone")
        c_now, c_prev = self.rigid_speed_coefficients(bank, pair[0])
        b, a = butter2_lowpass(cutoff, self.p.dt)
        ticks = int(np.ceil(40.0 / (2.0 * np.pi * cutoff * self.p.dt)))
        impulse = np.zeros(ticks)
        impulse[0], impulse[1] = c_now, c_prev
        response = lfilter(b, a, impulse)
        variance = float(first.R[0, 0] + second.R[0, 0])
        return float(np.sqrt(variance * np.sum(response**2)))

    def wind(
        self,
        columns: np.ndarray,
        v_guess: np.ndarray,
        moved: np.ndarray | None = None,
        stalled: np.ndarray | None = None,
    ) -> np.ndarray:
        """Wind speed of observer ``columns[i]`` (shape (m, n)) for every row: (m, n) m/s, one inversion call.

        ``v_guess`` (m, n) is the previous estimate of each: WARM_ITERATIONS from it suffice where the torque moved
        little since. ``moved`` (m, n) bool (None: none): the estimates whose observer changed since that guess was
        made. Their guess belongs to another observer's torque, which a fault the detector has not yet caught may
        have taken metres per second away, so they go on to SETTLE_ITERATIONS: enough to cross the whole
        [WIND_MIN, WIND_MAX] range at the 20 % steps of a flat branch, so the result is the new torque's root
        whatever the guess (``aero.wind_from_torque``; the same iterations continued, so unmoved rows and a guess
        already at the root are unchanged).

        ``stalled`` (n,) bool (None: none): the rows whose operating point is on τ(v)'s stalled branch (λ below
        the stall hump's), which are region 1's (``builtin.UIOBankEstimator``: the torque reference below
        ``POWER_SPEED_MIN_TORQUE`` × rated, where the design model's steady states have λ ≤ 2.2 and the hump is at
        λ ≈ 3.5–4.7). With negative pitch τ(v) rises, falls through the hump and rises again, and a torque between
        the trough's and the hump's levels has three roots; the iteration from a guess below the hump (an estimate
        a fault took low) returns the lowest, the unstalled one, metres per second below region 1's wind. A moved
        estimate on those rows is also inverted from WIND_MAX: from above, Newton descends the stalled branch to
        its root where the branch reaches the torque, and otherwise crosses the trough to the one root below, the
        same as from the guess. That result replaces the guess's where it is a root above it by more than
        DISTINCT_ROOT (relative): the stalled root. Where τ(v) has one root (β ≥ 0: at most a flat plateau) the
        two are the same root and the guess's is kept."""
        torque, omega_r = self._groups[0], self._groups[1]  # the published ω̂_r (see the module docstring)
        if self._fast is not None:  # the gathers and the warm iterations below by one kernel
            v = self._fast.column_winds(
                self._filtered, torque.start, omega_r.start, columns, v_guess, self.p.radius,
                self.p.aero_torque_gain, WARM_ITERATIONS,
            )  # fmt: skip
            if moved is None or not moved.any():
                return v
        rows = np.broadcast_to(np.arange(self.n), columns.shape)
        invert = aero.wind_from_torque if self._fast is None else self._fast.wind_from_torque
        tau = self._filtered[rows, torque.start + columns]
        speed = self._filtered[rows, omega_r.start + columns]
        pitch = np.broadcast_to(self.pitch_filtered, columns.shape)
        if self._fast is None:
            v = invert(tau, speed, pitch, v_guess, self.p, iterations=WARM_ITERATIONS)
        if moved is not None and moved.any():
            at = np.nonzero(moved)
            v[at] = invert(tau[at], speed[at], pitch[at], v[at], self.p, iterations=SETTLE_ITERATIONS - WARM_ITERATIONS)
            if stalled is not None:
                self._stalled_root(v, moved & stalled, tau, speed, pitch, invert)
        return v

    def _stalled_root(self, v: np.ndarray, rows: np.ndarray, tau, speed, pitch, invert) -> None:
        """``wind``'s stalled root, in place on the entries ``rows`` (m, n) bool of ``v``: the iterate from WIND_MAX
        (SETTLE_ITERATIONS) where it is a root of τ̂ (|τ_r(v) − τ̂| ≤ DISTINCT_ROOT |τ̂|, ``aero.rotor_torque``) above
        ``v`` by more than DISTINCT_ROOT. Where τ̂ lies within a hair of the trough's level, the iterate may step past
        the trough to the unstalled root (1 of 109 three-root cases in a random probe of region 1's ω_r and
        β ∈ [−2, 1] deg); ``v`` is then kept."""
        if not rows.any():
            return
        at = np.nonzero(rows)
        start = np.full(len(at[0]), aero.WIND_MAX)
        top = invert(tau[at], speed[at], pitch[at], start, self.p, iterations=SETTLE_ITERATIONS)
        residual = np.abs(aero.rotor_torque(top, speed[at], pitch[at], self.p) - tau[at])
        higher = (top > v[at] * (1.0 + DISTINCT_ROOT)) & (residual <= DISTINCT_ROOT * np.abs(tau[at]))
        v[at] = np.where(higher, top, v[at])
