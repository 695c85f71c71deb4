"""The fault-free reconstruction noise, predicted from the observer and the sensors' accuracy: the design basis of
the detection threshold (``service.hydro.detector``). No simulation of the plant and no fault data enter.

Without a fault, f̂_a,filt is the observer's answer to measurement noise. Inside the boundary layer the
injection (33) is v ≈ −ρ P_2 e_y/δ, linear in e_y while ‖P_2 e_y‖ ≪ δ: ±0.1 % noise keeps ‖P_2 e_y‖ near 1 % of
δ, ±2 % near a fifth (where the saturation of (33) can only shrink the response; the tests compare the
prediction with the simulated plant at both levels). The observer with its filter (37) is then a linear system
from the noise to f̂_filt:

    f̂_filt,j[k] = Σ_c Σ_i h_j,c[i] ν_c[k − i]                 (ν_c: noise of reading c, per unit of y_N,c)

``noise_response`` measures h numerically on the registered observer itself (any ``HYDRO_OBSERVERS`` entry):
a batch of six rows held at the closed-loop equilibrium of the design wind (``wwcore.hydro_model.equilibrium``);
row 1 + c gets a one-sample impulse ε y_N,c on reading c, row 0 none; (row 1 + c − row 0)/ε is h_·,c. The
design readings y_N are the rated values (ω_r,rated, ω_g,N, the rated generator torque, full strokes), which
bound the partial-load readings from above. For the TS-SMO, 𝓕_2⁺ picks the x̃_p, x̃_M channels whose model is
the actuator lag alone, so h_j,c = 0 for c ≠ x̃_j and h does not depend on the operating point (tested at
5 … 11 m/s).

With a relative measurement error uniform within ±a (the sensor specification, the paper's "noise up to
±2 %"), each reading's noise is white with standard deviation σ_ν = a/√3 per unit, so

    σ_j = (a/√3) ‖h_j‖₂           and the worst case       |f̂_filt,j| ≤ a ‖h_j‖₁.

With the paper's τ = 0.1 s, ‖h_j‖₂ = 0.91 and ‖h_j‖₁ = 0.98; with τ = 0.05 s, 1.76 and 2.50: the filter (37)
passes the differentiated noise of the stroke reading (τ_p/τ is its high-frequency gain).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from service.hydro.ts_model import OUTPUT_STATES
from service.plugins import HYDRO_OBSERVERS
from wwcore.hydro_model import equilibrium
from wwcore.hydro_params import HydroParams

DESIGN_WIND = 7.5  # m/s, the operating point of the linearisation (the shipped scenarios' mean wind)
SETTLE_SAMPLES = 100  # samples at the equilibrium before the impulse
BLOCK = 100  # samples per block of the response; it is followed until a block adds < TAIL of its energy
TAIL = 1e-12
MAX_SAMPLES = 20_000
EPSILON = 1e-6  # per unit of y_N: small enough to stay linear, large enough for float64


def rated_readings(p: HydroParams) -> np.ndarray:
    """y_N: the rated value of each reading [ω_r, ω_g, T_g, x̃_p, x̃_M], the scale of its relative noise."""
    return np.array([p.omega_r_rated, p.omega_g_N, p.rated_generator_torque, 1.0, 1.0])


@dataclass(frozen=True)
class NoiseResponse:
    """h (samples, 5 readings, 2 actuators) of f̂_filt per unit of y_N, and its norms per actuator; h_a the same
    of the unfiltered reconstruction f̂_a (35) (None for an observer measured without it)."""

    h: np.ndarray
    h_a: np.ndarray | None = None

    @property
    def l2(self) -> np.ndarray:
        """‖h_j‖₂ over samples and readings (2,)."""
        return np.sqrt((self.h**2).sum(axis=(0, 1)))

    @property
    def l1(self) -> np.ndarray:
        """‖h_j‖₁ over samples and readings (2,)."""
        return np.abs(self.h).sum(axis=(0, 1))

    def sigma(self, noise_pct: float) -> np.ndarray:
        """σ_j of f̂_filt,j for a relative error uniform within ±noise_pct % on every reading (2,)."""
        return noise_pct / 100.0 / np.sqrt(3.0) * self.l2

    def worst(self, noise_pct: float) -> np.ndarray:
        """The largest |f̂_filt,j| such noise can produce (2,)."""
        return noise_pct / 100.0 * self.l1


def noise_response(observer: str, settings: dict[str, Any], params: HydroParams) -> NoiseResponse:
    """h of the observer ``observer`` with ``settings`` (module docstring); cached per configuration."""
    frozen = tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in settings.items()))
    return _response(observer, frozen, params, DESIGN_WIND)


@functools.lru_cache(maxsize=32)
def _response(observer: str, settings: tuple[tuple[str, Any], ...], params: HydroParams, wind: float) -> NoiseResponse:
    eq = equilibrium(np.array([wind]), params)
    rows = 1 + len(OUTPUT_STATES)
    y = np.repeat(eq.x[:, list(OUTPUT_STATES)], rows, axis=0)
    u = np.repeat(eq.u, rows, axis=0)
    obs = HYDRO_OBSERVERS.create(observer, n=rows, params=params, settings=dict(settings))
    for _ in range(SETTLE_SAMPLES):
        obs.step(y, u)
    kicked = y.copy()
    kicked[1:] += np.diag(EPSILON * rated_readings(params))
    first = obs.step(kicked, u)
    out, raw = [first.f_filt], [first.f_hat]
    total = float(np.sum((out[0][1:] - out[0][:1]) ** 2))
    while len(out) < MAX_SAMPLES:
        block = [obs.step(y, u) for _ in range(BLOCK)]
        out.extend(r.f_filt for r in block)
        raw.extend(r.f_hat for r in block)
        energy = float(sum(np.sum((r.f_filt[1:] - r.f_filt[:1]) ** 2) for r in block))
        total += energy
        if energy <= TAIL * total:
            break
    f, f_a = np.array(out), np.array(raw)  # (samples, rows, 2)
    h = (f[:, 1:, :] - f[:, :1, :]) / EPSILON
    h_a = (f_a[:, 1:, :] - f_a[:, :1, :]) / EPSILON
    return NoiseResponse(np.nan_to_num(h), np.nan_to_num(h_a))
