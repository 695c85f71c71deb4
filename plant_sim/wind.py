r"""Wind of the benchmark turbine (PARAMETERS.md a.5): scenario mean, Kaimal turbulence, rotational sampling,
wind shear and tower shadow, per blade, for a batch of n turbines.

The benchmark's wind model (Odgaard, Stoustrup & Kinnaert 2009) is built from the turbulence and rotational-sampling
filters of Sørensen, Hansen & Rosas (2002, "Wind models for simulation of power fluctuations from wind farms",
J. Wind Eng. Ind. Aerodyn. 90) and the shear and tower-shadow expressions of Dolan & Lehn (2006, "Simulation model
of wind turbine 3p torque oscillations due to wind shear and tower shadow", IEEE Trans. Energy Convers. 21(3)).

**Turbulence** (0.05 s samples, [BENCH] a.5). Point turbulence at hub height:

.. math::

    u_p = σ(t)\,\frac{H_K * w}{σ_1},\qquad σ(t) = \mathrm{TI}\; v_m(t),\qquad
    H_K(s) = \frac{0.0182\,(sτ_K)^2 + 1.3653\,sτ_K + 0.9846}{1.3463\,(sτ_K)^2 + 3.7593\,sτ_K + 1},\quad
    τ_K = \frac{L}{2π\bar v}

with w unit-variance white noise from the turbine's own generator. H_K approximates the Kaimal spectrum in the form
Sørensen et al. use, S(f) = σ² (L/v̄) / (1 + 1.5 f L/v̄)^{5/3} (the IEC form 4σ²(L₁/v̄)/(1 + 6 f L₁/v̄)^{5/3}
with L₁ = L/4), within ±20 % in PSD for f L/v̄ ≤ 30.

The benchmark's gain ``turb_int·sqrt(L·v̄)/100/sqrt(2)``, with turb_int in percent, is σ √(L/(2v̄)) (m/s/√Hz).
It is the amplitude of *continuous* white noise whose one-sided PSD after H_K (H_K(0) ≈ 1) is σ²L/v̄, the Kaimal
value at f → 0. Sampled every T_s, that means unit-variance samples scaled by σ√(L/(2v̄ T_s)). Because H_K keeps a
high-frequency floor (0.0182/1.3463), that literal gain gives σ_u = 1.00–1.12 TI·v̄ for v̄ = 25–4 m/s. We keep the
filter shape and divide instead by σ₁, the exact standard deviation of the discretised H_K for unit-variance input
(from the discrete Lyapunov equation). The hub turbulence then has σ_u = TI·v_m.

**Rotational sampling** ([BENCH] a.5, filters of Sørensen et al. 2002), τ_r = R/v̄:

.. math::

    u_0 = H_0 * u_p,\quad H_0(s) = \frac{4.7869\,sτ_r + 0.9904}{7.6823\,(sτ_r)^2 + 7.3518\,sτ_r + 1},\qquad
    u_3 = H_3 * u_p,\quad H_3(s) = \frac{0.2766\,sτ_r + 0.0307}{0.3691\,(sτ_r)^2 + 1.7722\,sτ_r + 1}

u_0 is the rotor-averaged (0th harmonic) turbulence. u_3 is the amplitude of its 3rd harmonic, which we modulate
with the rotor azimuth ψ. That modulation is [PROPOSED]: the benchmark gives the filters, not the modulation. The
rotor-level wind before shear and tower shadow is

.. math::  w = v_m + u_0 + u_3 \cos 3ψ

cos 3ψ_i is the same for the three blades (ψ_i = ψ + 2π(i−1)/3), so all three blades see this term and the rotor
mean keeps it as a 3P component.

Filter coefficients depend on v̄. They are recomputed once per chunk (CHUNK_SAMPLES samples, 20 s) from the mean of
v_m over that chunk, by the bilinear transform (``scipy.signal.cont2discrete``). The filter states (``lfilter``'s
zi) carry over from chunk to chunk, so a slowly varying mean changes the spectrum smoothly. σ(t) follows v_m at
every sample. Before t = 0 the filters run through a burn-in of ten times their slowest time constant, so the
turbulence is stationary from the first tick. The 0.05 s samples are brought to the plant tick by **linear
interpolation**.

**Shear and tower shadow** (Dolan & Lehn 2006; deterministic, per blade; re-derived here from the span integrals
below, the paper's equation numbers were not at hand). Blade azimuth θ is measured from
vertical-up, in the direction of rotation. The blade's equivalent wind is the span average of the local wind with
weight 2r/R², the weight for which the rotor mean has the benchmark's factor m = 1 + α(α−1)R²/(8H²):

.. math::

    F(θ) = 1 + \tfrac{2α}{3}\tfrac{R}{H}\cos θ + \tfrac{α(α-1)}{4}\bigl(\tfrac{R}{H}\bigr)^2\cos^2 θ
           + \tfrac{α(α-1)(α-2)}{15}\bigl(\tfrac{R}{H}\bigr)^3\cos^3 θ
           + m\,\frac{a^2}{x^2}\Bigl[\frac{\ln(1+z)}{z} - \frac{2}{1+z}\Bigr]_{\cos θ < 0},
    \qquad z = \frac{R^2\sin^2θ}{x^2}

The first line is the binomial series of the power law (1 + r cos θ/H)^α to third order, averaged over the span
with weight 2r/R². The bracket is the span average of the potential flow round the tower,
u/V = 1 + a²(y² − x²)/(x² + y²)² with y = r sin θ. Following Dolan & Lehn it acts only on the blade passing below
the hub (cos θ < 0), and it is −m a²/x² when the blade points straight down. At the horizontal positions it jumps
by m·0.0044 (the potential flow speeds up beside the tower). For the rotor (mean over the blades):

.. math::  \bar F(ψ) = m + \tfrac{α(α-1)(α-2)}{60}\bigl(\tfrac{R}{H}\bigr)^3\cos 3ψ + \text{tower shadow},

which has period 2π/3. Constants: α, H = 87 m and R = 57.5 m from the scenario and ``TurbineParams``. Tower radius
a = 2.2 m and blade-to-tower distance x = 4.7 m are the benchmark's ``a`` and ``k`` (a.5). a.1 also lists
r0 = 1.5 m "used in the tower-shadow expression" (``TurbineParams.tower_radius``). The Dolan–Lehn form has no
third length, so r0 is not used. That is our reading, not a documented fact.

Outputs per blade and tick: ``blades = w F(ψ_i)``, ``rotor`` = the mean of the three blade winds (= w F̄(ψ)),
``hub = v_m + u_p`` (a point anemometer: no rotor averaging, no shear or shadow) and ``mean = v_m``. F is tabulated
over azimuth: 12 288 points per turn, linear interpolation within each cell from its one-sided end values, so the
jump is exact and the error is < 1e-5. So ``sample`` costs about fifteen numpy operations on (n,) and (n, 3)
arrays, plus one chunk of filtering every 20 s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg, signal

from wwcore.backend import fast_module, resolve_backend
from wwcore.scenario.wind import WindSpec
from wwcore.turbine_params import TurbineParams

TURBULENCE_SAMPLE_TIME = 0.05  # s, T_sample of the benchmark's turbulence [BENCH] a.5
CHUNK_SAMPLES = 400  # turbulence samples drawn and filtered at a time (20 s)
BURN_IN_TIME_CONSTANTS = 10.0  # – burn-in length in slowest filter time constants
BURN_IN_MAX_S = 3000.0  # s, cap on the burn-in

# filters in normalised Laplace variable s·τ, coefficients highest power first [BENCH] a.5
KAIMAL_NUM = (0.0182, 1.3653, 0.9846)  # τ_K = L/(2π v̄)
KAIMAL_DEN = (1.3463, 3.7593, 1.0)
HARMONIC0_NUM = (4.7869, 0.9904)  # τ_r = R/v̄
HARMONIC0_DEN = (7.6823, 7.3518, 1.0)
HARMONIC3_NUM = (0.2766, 0.0307)
HARMONIC3_DEN = (0.3691, 1.7722, 1.0)

TOWER_SHADOW_A = 2.2  # m, tower radius a of the Dolan–Lehn expression [BENCH] a.5 "a"
TOWER_SHADOW_X = 4.7  # m, distance x from the tower axis to the rotor plane [BENCH] a.5 "k"

AZIMUTH_TABLE_SIZE = 3 * 4096  # table points per turn; a multiple of 3, so the blade offsets are whole table steps
TWO_PI = 2.0 * math.pi
BLADE_OFFSETS = np.array([0.0, TWO_PI / 3.0, 2.0 * TWO_PI / 3.0])  # rad, azimuth of blades 1–3 minus blade 1


# ---- deterministic parts ------------------------------------------------------------------------------------
def mean_wind(spec: WindSpec, t: np.ndarray) -> np.ndarray:
    """The scenario's mean wind v_m(t) in m/s: piecewise linear through ``spec.mean``, held outside."""
    times, speeds = zip(*spec.mean, strict=True)
    return np.interp(t, times, speeds)


def shear_factor(theta: np.ndarray, alpha: float, radius: float, hub_height: float) -> np.ndarray:
    """Blade equivalent wind / hub wind for the power-law shear (module docstring, F without the tower term)."""
    c = np.cos(theta) * (radius / hub_height)
    return 1.0 + c * (
        2.0 * alpha / 3.0 + c * (alpha * (alpha - 1.0) / 4.0 + c * alpha * (alpha - 1.0) * (alpha - 2.0) / 15.0)
    )


def mean_shear(alpha: float, radius: float, hub_height: float) -> float:
    """m = 1 + α(α−1)R²/(8H²): the rotor-mean level of the sheared wind [BENCH] a.5."""
    return 1.0 + alpha * (alpha - 1.0) * radius**2 / (8.0 * hub_height**2)


def tower_shadow_term(theta: np.ndarray, alpha: float, radius: float, hub_height: float) -> np.ndarray:
    """Tower-shadow term of F(θ): m (a²/x²)[ln(1+z)/z − 2/(1+z)], z = R² sin²θ/x², for cos θ < 0, else 0."""
    theta = np.asarray(theta, dtype=float)
    z = (radius / TOWER_SHADOW_X) ** 2 * np.sin(theta) ** 2
    safe = np.where(z > 1e-12, z, 1.0)
    ratio = np.where(z > 1e-12, np.log1p(safe) / safe, 1.0 - 0.5 * z)  # ln(1+z)/z → 1 − z/2 as z → 0
    term = mean_shear(alpha, radius, hub_height) * (TOWER_SHADOW_A / TOWER_SHADOW_X) ** 2 * (ratio - 2.0 / (1.0 + z))
    return np.where(np.cos(theta) < 0.0, term, 0.0)


def blade_factor(theta: np.ndarray, spec: WindSpec, params: TurbineParams) -> np.ndarray:
    """F(θ): a blade's equivalent wind over the rotor-level wind w, at blade azimuth θ (rad, 0 = up)."""
    f = shear_factor(theta, spec.shear_exponent, params.radius, params.hub_height)
    if spec.tower_shadow:
        f = f + tower_shadow_term(theta, spec.shear_exponent, params.radius, params.hub_height)
    return f


def rotor_factor(azimuth: np.ndarray, spec: WindSpec, params: TurbineParams) -> np.ndarray:
    """F̄(ψ): the mean of F over the three blades, for blade-1 azimuth ψ (rad)."""
    psi = np.asarray(azimuth, dtype=float)[..., None] + BLADE_OFFSETS
    return blade_factor(psi, spec, params).mean(axis=-1)


# ---- turbulence -----------------------------------------------------------------------------------------------
def _in_s(coeffs: Sequence[float], tau: float) -> list[float]:
    """Polynomial in sτ → polynomial in s (highest power first): the coefficient of (sτ)^k times τ^k."""
    return [c * tau ** (len(coeffs) - 1 - i) for i, c in enumerate(coeffs)]


def _discretise(num: Sequence[float], den: Sequence[float], tau: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of H(sτ) discretised at dt by the bilinear transform."""
    b, a, _ = signal.cont2discrete((_in_s(num, tau), _in_s(den, tau)), dt, method="bilinear")
    return np.ravel(b), np.ravel(a)


def _output_std(b: np.ndarray, a: np.ndarray) -> float:
    """Stationary standard deviation of the output of b/a for unit-variance white input (discrete Lyapunov)."""
    A, B, C, D = signal.tf2ss(b, a)
    P = linalg.solve_discrete_lyapunov(A, B @ B.T)
    return float(np.sqrt((C @ P @ C.T + D @ D.T).item()))


def kaimal_filter(mean_speed: float, length_scale: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of the discretised H_K for mean wind v̄ (m/s), scaled to unit output variance for unit input."""
    b, a = _discretise(KAIMAL_NUM, KAIMAL_DEN, length_scale / (2.0 * math.pi * mean_speed), dt)
    return b / _output_std(b, a), a


def harmonic_filters(mean_speed: float, radius: float, dt: float) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """((b0, a0), (b3, a3)): the discretised 0th- and 3rd-harmonic rotational-sampling filters, τ_r = R/v̄."""
    tau = radius / mean_speed
    return _discretise(HARMONIC0_NUM, HARMONIC0_DEN, tau, dt), _discretise(HARMONIC3_NUM, HARMONIC3_DEN, tau, dt)


def slowest_time_constant(mean_speed: float, length_scale: float, radius: float) -> float:
    """The slowest pole of H_K, H_0, H_3 at v̄, in s."""
    taus = []
    for den, tau in (
        (KAIMAL_DEN, length_scale / (2.0 * math.pi * mean_speed)),
        (HARMONIC0_DEN, radius / mean_speed),
        (HARMONIC3_DEN, radius / mean_speed),
    ):
        taus.append(tau / np.abs(np.roots(den).real).min())
    return max(taus)


class TurbulenceStreams:
    """Point, 0th- and 3rd-harmonic turbulence (u_p, u_0, u_3) for n turbines at TURBULENCE_SAMPLE_TIME, in chunks.

    Turbine i draws only from ``rngs[i]``, and its filters run on row i alone, so its turbulence does not depend
    on the other rows. ``next_chunk`` returns samples k·T_s for k = s0+1 … s0+CHUNK_SAMPLES. The sample at s0
    (t = 0 for the first chunk) is the last of the previous chunk, or of the burn-in.
    """

    def __init__(self, spec: WindSpec, params: TurbineParams, rngs: Sequence[np.random.Generator]):
        self.spec = spec
        self.radius = params.radius
        self.rngs = list(rngs)
        self.n = len(self.rngs)
        self.dt = TURBULENCE_SAMPLE_TIME
        self.next_index = 0  # index of the last sample produced; the next chunk starts after it
        v0 = float(mean_wind(spec, 0.0))
        burn_in_s = min(
            BURN_IN_TIME_CONSTANTS * slowest_time_constant(v0, spec.length_scale_m, self.radius), BURN_IN_MAX_S
        )
        n_burn = math.ceil(burn_in_s / self.dt)
        self._zk = np.zeros((self.n, 2))
        self._z0 = np.zeros((self.n, 2))
        self._z3 = np.zeros((self.n, 2))
        out = self._filter(np.full(n_burn, v0), v0)
        self.last = tuple(a[:, -1] for a in out)  # (u_p, u_0, u_3) at t = 0

    def _filter(self, vm: np.ndarray, vbar: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = np.stack([rng.standard_normal(vm.size) for rng in self.rngs])
        bk, ak = kaimal_filter(vbar, self.spec.length_scale_m, self.dt)
        unit, self._zk = signal.lfilter(bk, ak, w, axis=-1, zi=self._zk)
        up = unit * (self.spec.turbulence_intensity * vm)  # σ(t) = TI v_m(t)
        (b0, a0), (b3, a3) = harmonic_filters(vbar, self.radius, self.dt)
        u0, self._z0 = signal.lfilter(b0, a0, up, axis=-1, zi=self._z0)
        u3, self._z3 = signal.lfilter(b3, a3, up, axis=-1, zi=self._z3)
        return up, u0, u3

    def next_chunk(self) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(t (S,), (u_p, u_0, u_3) each (n, S)) for the next CHUNK_SAMPLES samples, in s and m/s."""
        t = (self.next_index + 1 + np.arange(CHUNK_SAMPLES)) * self.dt
        vm = mean_wind(self.spec, t)
        out = self._filter(vm, float(vm.mean()))
        self.next_index += CHUNK_SAMPLES
        self.last = tuple(a[:, -1] for a in out)
        return t, out


# ---- the field the plant samples ---------------------------------------------------------------------------
@dataclass
class WindSample:
    """Wind of one tick for n turbines, m/s."""

    blades: np.ndarray  # (n, 3): equivalent wind of each blade (torque-equivalent over the span)
    hub: np.ndarray  # (n,): point wind at hub height, as an anemometer sees it (no rotor averaging)
    rotor: np.ndarray  # (n,): rotor-effective wind, the mean of the three blade winds (the "true wind")
    mean: np.ndarray  # (n,): the scenario's mean wind


class WindField:
    """Per-tick wind for a batch of n turbines: ``sample(k, azimuth)`` for k = 0, 1, 2, … (module docstring)."""

    def __init__(
        self,
        spec: WindSpec,
        params: TurbineParams,
        rngs: Sequence[np.random.Generator],
        dt: float,
        backend: str | None = None,
    ):
        self.spec = spec
        # ``"numba"``: ``sample``'s interpolation by ``plant_sim.turbine.fast.blade_winds``, the same numbers
        self._fast = fast_module("plant_sim.turbine.fast") if resolve_backend(backend) == "numba" else None
        self.n = len(rngs)
        self.dt = float(dt)
        self._streams = TurbulenceStreams(spec, params, rngs)
        # F tabulated on a uniform grid over [0, 2π + 4π/3]: blade azimuths (ψ mod 2π) + offsets stay inside, and
        # linear interpolation is an index computation. Each cell holds its own one-sided end values, so the jump
        # of the tower term at the horizontal blade positions (grid points) is reproduced exactly.
        per_turn = AZIMUTH_TABLE_SIZE
        step = TWO_PI / per_turn
        left = np.arange(per_turn * 5 // 3 + 1) * step
        self._table = blade_factor(left + 1e-9, spec, params)
        self._slope = blade_factor(left + (step - 1e-9), spec, params) - self._table  # per grid step
        self._per_rad = per_turn / TWO_PI
        self._offsets = BLADE_OFFSETS * self._per_rad  # in grid steps: exact multiples of per_turn/3
        self._chunk_fast = None  # ``plant_sim.farm.fast`` where a subclass sets it (``_chunk_at_ticks``)
        self._next_k = 0
        self._chunk_start = 0
        self._chunk_end = 0  # ticks [start, end) are in the arrays below
        self._hub = self._base = self._u3 = self._mean = np.empty((0, self.n))
        # (v_m + u_0, u_3, v_hub, v_m) (ticks, n) of the chunk (``advance``'s row j), new arrays at each refill
        self.chunk = (self._base, self._u3, self._hub, self._mean)

    def _refill(self) -> None:
        """Filter the next turbulence chunk and interpolate it (and v_m) to the ticks it covers."""
        t0 = self._streams.next_index * TURBULENCE_SAMPLE_TIME
        last = self._streams.last
        t, fresh = self._streams.next_chunk()
        k_end = math.ceil(t[-1] / self.dt - 1e-9)
        ticks = np.arange(self._chunk_end, k_end)
        p = (ticks * self.dt - t0) / TURBULENCE_SAMPLE_TIME  # position in samples after the kept one, in [0, S)
        q = np.minimum(p.astype(int), CHUNK_SAMPLES - 1)
        frac = p - q
        vm = mean_wind(self.spec, ticks * self.dt)
        self._mean, self._hub, self._base, self._u3 = self._chunk_at_ticks(last, fresh, q, frac, vm)
        for shared in (self._mean, self._hub):  # ``sample`` hands out rows of these: read-only views
            shared.flags.writeable = False
        self.chunk = (self._base, self._u3, self._hub, self._mean)
        self._chunk_start, self._chunk_end = int(ticks[0]), k_end

    def _chunk_at_ticks(
        self,
        last: tuple[np.ndarray, ...],
        fresh: tuple[np.ndarray, ...],
        q: np.ndarray,
        frac: np.ndarray,
        vm: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(v_m, v_m + u_p, v_m + u_0, u_3), each (T, n), at the chunk's ticks: the turbulence samples (``last``
        (u_p, u_0, u_3) each (n,) at the kept sample, ``fresh`` each (n, S) after it) interpolated linearly at the
        ticks' positions q + frac (T,) samples after the kept one; ``vm`` (T,) the ticks' mean wind. With
        ``_chunk_fast`` (the compiled ``FarmWindField``'s) by ``chunk_at_ticks``, the same operations on each
        element."""
        if self._chunk_fast is not None:
            out = np.empty((4, q.size, self.n))
            self._chunk_fast.chunk_at_ticks(last, fresh, q, frac, vm, out)
            return out[0], out[1], out[2], out[3]
        w = frac[:, None]

        def at_ticks(prev: np.ndarray, chunk: np.ndarray) -> np.ndarray:
            s = np.concatenate((prev[:, None], chunk), axis=1).T  # (S+1, n)
            return s[q] * (1.0 - w) + s[q + 1] * w  # (T, n), linear interpolation

        up, u0, u3 = (at_ticks(a, b) for a, b in zip(last, fresh, strict=True))
        vm = vm[:, None]
        return np.repeat(vm, self.n, axis=1), vm + up, vm + u0, u3

    def advance(self, k: int) -> int:
        """Move on to tick k (0, 1, 2, … in turn), the next chunk filtered when k needs it; k's row in the chunk's
        arrays (``chunk``)."""
        if k != self._next_k:
            raise ValueError(f"WindField.sample expects tick {self._next_k}, got {k}")
        self._next_k = k + 1
        if k >= self._chunk_end:
            self._refill()
        return k - self._chunk_start

    def interpolation(self) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """(F's table, its slope per grid step, grid steps per rad, the blades' offsets in grid steps): ``sample``'s
        azimuth interpolation, for a compiled ``sample``."""
        return self._table, self._slope, self._per_rad, self._offsets

    def sample(self, k: int, azimuth: np.ndarray) -> WindSample:
        """Wind at tick k (t = k·dt) for blade-1 azimuth ``azimuth`` (n,) in rad; k must be 0, 1, 2, … in turn."""
        j = self.advance(k)
        if self._fast is not None:
            blades, rotor = np.empty((self.n, 3)), np.empty(self.n)
            azimuth = np.ascontiguousarray(azimuth, dtype=float)
            self._fast.blade_winds(
                azimuth,
                self._table,
                self._slope,
                self._per_rad,
                self._offsets,
                self._base[j],
                self._u3[j],
                blades,
                rotor,
            )
            return WindSample(blades=blades, hub=self._hub[j], rotor=rotor, mean=self._mean[j])
        x = np.mod(azimuth, TWO_PI)[:, None] * self._per_rad + self._offsets  # (n, 3) in grid steps
        i = x.astype(np.intp)
        f = np.take(self._table, i) + np.take(self._slope, i) * (x - i)  # F(ψ_i), linear interpolation
        w = self._base[j] + self._u3[j] * np.cos(3.0 * azimuth)  # w = v_m + u_0 + u_3 cos 3ψ
        blades = w[:, None] * f
        # Row-wise, so independent of the other turbines bit for bit; the blades added in sum(axis=1)'s order,
        # without the reduction machinery's overhead on a 3-wide axis.
        rotor = ((blades[:, 0] + blades[:, 1]) + blades[:, 2]) * (1.0 / 3.0)
        return WindSample(blades=blades, hub=self._hub[j], rotor=rotor, mean=self._mean[j])
