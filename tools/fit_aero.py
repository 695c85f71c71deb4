"""Fit the analytic C_p(λ, β) of ``wwcore/aero.py`` to the benchmark's reference surface; print its coefficients.

    .venv/bin/python tools/fit_aero.py [DATA]

DATA is the directory holding ``benchmark_4p8mw_cp.csv`` (or that CSV itself); default ``../shared/data``
relative to the repository root. The script prints the fit errors and a coefficient block to paste between the
``# BEGIN fit_aero`` / ``# END fit_aero`` markers of ``wwcore/aero.py``.

Method (variable projection): C_p = Σ_ij M_ij f_i(β) s_j(λ, β) is linear in the 36 coefficients M once the six
shape parameters (b0, b1, β_h, β_k, w_k, x_ref) are fixed, so for every trial shape M is the weighted linear
least-squares solution, and ``scipy.optimize.least_squares`` fits the shape on the projected residual from a
fixed set of starts. Weights: 1 in the operating envelope (λ 3–12, β −2–30 deg) and for λ < 3 (start-up and
stand-still torque), 3 around C_p,max (λ 7–9, β −1–1 deg), 0.05 on the rest of the table (λ ≥ 3, β > 30 deg).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares, minimize

from wwcore import aero

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO_ROOT.parent / "shared" / "data"
CP_FILE = "benchmark_4p8mw_cp.csv"
OUTSIDE_WEIGHT = 0.05  # weight of the table points outside the envelope with λ ≥ 3 (β > 30 deg)
LOW_TSR = 3.0  # below this λ (start-up, stand-still) the points weigh 1 at every pitch
PEAK_WEIGHT = 3.0  # weight of the points around C_p,max (λ 7–9, β −1–1 deg), to pin its value and place
SHAPE_LOWER = (5.0, 0.0, 0.1, 5.0, 1.0, 0.0)  # (b0, b1, β_h, β_k, w_k, x_ref) bounds; w_k ≥ 1 deg keeps σ smooth
SHAPE_UPPER = (60.0, 20.0, 20.0, 60.0, 20.0, 0.3)
FIRST_SHAPE = (21.5, 4.4, 3.0, 21.5, 0.6, 0.125)
N_STARTS = 16  # the first start is FIRST_SHAPE, the others log-normal perturbations of it (fixed seed)


@dataclass(frozen=True)
class Fit:
    shape: tuple[float, ...]
    coeffs: np.ndarray  # (6, 6): M[i, j], pitch feature i, λ-term j
    rms_envelope: float
    max_envelope: float
    max_table: float
    cp_max: float
    tsr_at_max: float
    pitch_at_max: float


def model_cp(tsr: np.ndarray, pitch_deg: np.ndarray, shape: tuple[float, ...], coeffs: np.ndarray) -> np.ndarray:
    """C_p of the analytic form for given shape and coefficients (inputs inside the table range)."""
    f = aero.pitch_features(np.broadcast_to(pitch_deg, np.broadcast_shapes(np.shape(tsr), np.shape(pitch_deg))), shape)
    return np.einsum("i...,ij,j...->...", f, coeffs, aero.tsr_slots(tsr, pitch_deg, shape))


def design_matrix(tsr: np.ndarray, pitch_deg: np.ndarray, shape: tuple[float, ...]) -> np.ndarray:
    """(N, 36) matrix whose column 6 i + j is f_i(β) s_j(λ, β), for flat arrays of N points."""
    f = aero.pitch_features(pitch_deg, shape)
    s = aero.tsr_slots(tsr, pitch_deg, shape)
    return (f[:, None, :] * s[None, :, :]).reshape(f.shape[0] * s.shape[0], -1).T


def envelope_mask(tsr: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    (l0, l1), (b0, b1) = aero.ENVELOPE_TSR, aero.ENVELOPE_PITCH_DEG
    return (tsr >= l0) & (tsr <= l1) & (pitch_deg >= b0) & (pitch_deg <= b1)


def fit_surface(tsr: np.ndarray, pitch_deg: np.ndarray, cp: np.ndarray) -> Fit:
    """Fit to the table cp (m, k) over the grid tsr (m,) × pitch_deg (k,)."""
    lam, beta = (a.ravel() for a in np.meshgrid(tsr, pitch_deg, indexing="ij"))
    y = cp.ravel()
    inside = envelope_mask(lam, beta)
    w = np.where(inside | (lam < LOW_TSR), 1.0, OUTSIDE_WEIGHT)
    w[(lam >= 7.0) & (lam <= 9.0) & (beta >= -1.0) & (beta <= 1.0)] = PEAK_WEIGHT

    def linear(shape: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        a = design_matrix(lam, beta, tuple(shape))
        if not np.all(np.isfinite(a)) or np.abs(a).max() > 1e8:
            return None
        m, *_ = np.linalg.lstsq(a * w[:, None], y * w, rcond=None)
        return m, a @ m - y

    def residual(shape: np.ndarray) -> np.ndarray:
        sol = linear(shape)
        return np.full(y.size, 10.0) if sol is None else w * sol[1]

    rng = np.random.default_rng(0)
    lo, hi = np.array(SHAPE_LOWER), np.array(SHAPE_UPPER)
    best = None
    for start in range(N_STARTS):
        x0 = np.array(FIRST_SHAPE) * (np.exp(rng.normal(0.0, 0.3, len(FIRST_SHAPE))) if start else 1.0)
        res = least_squares(residual, np.clip(x0, lo + 1e-6, hi - 1e-6), bounds=(lo, hi), max_nfev=400)
        if best is None or res.cost < best.cost:
            best = res
    shape = tuple(float(v) for v in best.x)
    m, r = linear(best.x)
    coeffs = m.reshape(6, -1)

    # the model's C_p,max: start from the best point of a fine grid near the optimum
    gl, gb = np.meshgrid(np.linspace(5.0, 11.0, 121), np.linspace(-2.0, 4.0, 121), indexing="ij")
    gc = model_cp(gl, gb, shape, coeffs)
    i = np.unravel_index(np.argmax(gc), gc.shape)
    opt = minimize(
        lambda p: -float(model_cp(np.array(p[0]), np.array(p[1]), shape, coeffs)),
        [gl[i], gb[i]],
        method="Nelder-Mead",
        bounds=[(aero.TSR_MIN, aero.TSR_MAX), (aero.PITCH_MIN_DEG, aero.ENVELOPE_PITCH_DEG[1])],
        options={"xatol": 1e-6, "fatol": 1e-10},
    )
    return Fit(
        shape=shape,
        coeffs=coeffs,
        rms_envelope=float(np.sqrt(np.mean(r[inside] ** 2))),
        max_envelope=float(np.abs(r[inside]).max()),
        max_table=float(np.abs(r).max()),
        cp_max=float(-opt.fun),
        tsr_at_max=float(opt.x[0]),
        pitch_at_max=float(opt.x[1]),
    )


def coefficient_block(fit: Fit) -> str:
    """The lines to paste between the markers of wwcore/aero.py."""
    rows = ",\n".join("        [" + ", ".join(f"{v:.12g}" for v in row) + "]" for row in fit.coeffs)
    shape = ", ".join(repr(float(f"{v:.12g}")) for v in fit.shape)
    return (
        "# BEGIN fit_aero\n"
        "# (b0, b1, β_h deg, β_k deg, w_k deg, x_ref)\n"
        f"SHAPE = ({shape})\n"
        "COEFFS = np.array(  # M[i, j]: f_i ∈ [1, h, h², sin β, sin² β, σ], λ-terms j ∈ [xE, E, λ, λ², λ³, λE]\n"
        f"    [\n{rows},\n    ]\n)\n"
        "# END fit_aero"
    )


def main(data: Path) -> int:
    path = data / CP_FILE if data.is_dir() else data
    if not path.is_file():
        print(f"reference table not found: {path}", file=sys.stderr)
        return 1
    tsr, pitch, cp = aero.read_reference_surface(path)
    fit = fit_surface(tsr, pitch, cp)
    print(f"reference: {path}  ({tsr.size} λ × {pitch.size} β)")
    print(f"envelope λ {aero.ENVELOPE_TSR}, β {aero.ENVELOPE_PITCH_DEG} deg:")
    print(f"  RMS |ΔC_p| = {fit.rms_envelope:.4f}   max |ΔC_p| = {fit.max_envelope:.4f}")
    print(f"whole table: max |ΔC_p| = {fit.max_table:.4f}")
    print(f"model C_p,max = {fit.cp_max:.4f} at λ = {fit.tsr_at_max:.3f}, β = {fit.pitch_at_max:.3f} deg")
    print()
    print(coefficient_block(fit))
    return 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", type=Path, default=DEFAULT_DATA, help="directory or CP CSV file")
    sys.exit(main(parser.parse_args().data))
