"""Fit the thrust rule of ``wwcore.thrust`` (one constant K) to published curves of pitch-regulated turbines.

    .venv/bin/python tools/fit_thrust.py [--reference-data ../shared/data]

Reads the power and thrust-coefficient curves of the NREL 5 MW, IEA 10 MW, IEA 15 MW and IEA 22 MW reference
turbines from FLORIS's turbine library and the V80's from ``v80_reference_curves.csv``; for each turbine it forms
c = C_p / C_p,max from its power curve (C_p = P / (½ρAv³), from its C_p maximum to cut-out) and fits
h(C_T) = K c by least squares in C_T. Then it checks the rule, untouched, against the NREL 5 MW C_p(λ, β) and
C_T(λ, β) surfaces FLORIS ships for its controller-dependent model, and prints the benchmark's steady C_T curve
(rated reference and two derated ones). The printed K goes into ``wwcore.thrust.THRUST_LOADING_K``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import floris
import numpy as np
import yaml
from scipy.optimize import minimize_scalar

from plant_sim.farm.operating_curve import steady_operating_curve
from wwcore import thrust
from wwcore.turbine_params import BENCHMARK

LIBRARY = Path(floris.__file__).parent / "turbine_library"
REFERENCE_TURBINES = ("nrel_5MW", "iea_10MW", "iea_15MW", "iea_22MW")
RHO = 1.225


def reference_curves(data_dir: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, float]]:
    """name → (wind m/s, power W, C_T, rotor diameter m)."""
    curves = {}
    for name in REFERENCE_TURBINES:
        spec = yaml.safe_load((LIBRARY / f"{name}.yaml").read_text())
        table = spec["power_thrust_table"]
        curves[name] = (
            np.array(table["wind_speed"], float),
            np.array(table["power"], float) * 1e3,
            np.array(table["thrust_coefficient"], float),
            float(spec["rotor_diameter"]),
        )
    lines = (data_dir / "v80_reference_curves.csv").read_text().splitlines()
    v80 = np.array([[float(x) for x in line.split(",")] for line in lines if line and line[0].isdigit()])
    curves["v80"] = (v80[:, 0], v80[:, 1] * 1e3, v80[:, 2], 80.0)
    return curves


def curve_points(curves: dict) -> list[tuple[str, float, float, float]]:
    """(turbine, wind, c = C_p/C_p,max, C_T) from each curve's C_p maximum to cut-out (25 m/s)."""
    points = []
    for name, (v, p, ct, d) in curves.items():
        keep = (v >= 3.5) & (v <= 25.01) & (p > 0)
        cp = p[keep] / (0.5 * RHO * np.pi * d * d / 4.0 * v[keep] ** 3)
        top = int(np.argmax(cp))
        for vv, c, t in zip(v[keep][top:], cp[top:] / cp.max(), ct[keep][top:], strict=True):
            points.append((name, float(vv), float(c), float(t)))
    return points


def fit(points) -> tuple[float, np.ndarray]:
    c = np.array([p[2] for p in points])
    ct = np.array([p[3] for p in points])

    def loss(k: float) -> float:
        return float(np.sum((thrust.thrust_from_power_coefficient(c, 1.0, k) - ct) ** 2))

    k = minimize_scalar(loss, bounds=(0.3, thrust.H_MAX), method="bounded").x
    return float(k), thrust.thrust_from_power_coefficient(c, 1.0, k) - ct


def surface_check(k: float) -> np.ndarray:
    data = np.load(LIBRARY / "demo_cp_ct_surfaces" / "nrel_5MW_demo_cp_ct_surface.npz")
    tsr, pitch, cp, ct = data["tsr_lut"], data["pitch_lut"], data["cp_lut"], data["ct_lut"]
    lam, beta = np.meshgrid(tsr, pitch, indexing="ij")
    keep = (lam >= 4.0) & (lam <= 9.5) & (beta >= -1.0) & (cp > 0.02)
    return thrust.thrust_from_power_coefficient(cp[keep] / cp.max(), 1.0, k) - ct[keep], lam[keep], beta[keep]


def main() -> None:
    shared = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    default = os.environ.get("WINDWARDEN_REFERENCE_DATA", str(shared))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference-data", default=default, help="directory holding v80_reference_curves.csv")
    args = parser.parse_args()
    points = curve_points(reference_curves(Path(args.reference_data)))
    k, res = fit(points)
    print(f"K = {k:.4f}  (C_T at C_p,max = {float(thrust.thrust_from_power_coefficient(1.0, 1.0, k)):.3f})")
    print(f"all {len(res)} points: RMS {np.sqrt(np.mean(res**2)):.3f}, max {np.abs(res).max():.3f}")
    for name in (*REFERENCE_TURBINES, "v80"):
        r = np.array([e for e, p in zip(res, points, strict=True) if p[0] == name])
        worst = max((abs(e), p[1]) for e, p in zip(res, points, strict=True) if p[0] == name)
        print(f"  {name:9s} n={len(r):3d} RMS {np.sqrt(np.mean(r**2)):.3f} max {worst[0]:.3f} at {worst[1]:g} m/s")
    err, lam, beta = surface_check(k)
    low = lam <= 8.0
    print(
        f"NREL 5 MW C_T(λ, β) surface, λ 4–9.5, β ≥ −1 deg, C_p > 0.02: {err.size} points, RMS "
        f"{np.sqrt(np.mean(err**2)):.3f}, max {np.abs(err).max():.3f} at λ = {lam[np.argmax(np.abs(err))]:g}, "
        f"β = {beta[np.argmax(np.abs(err))]:g}; λ ≤ 8: max {np.abs(err[low]).max():.3f}"
    )
    winds = np.array([5.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0, 17.0, 19.0, 21.0, 25.0])
    available = steady_operating_curve(BENCHMARK, winds)[0]
    print("benchmark steady C_T (wind: available power / 80 % / 50 % of it, farm controller derating by speed):")
    for v, p_avail in zip(winds, available, strict=True):
        cts = [float(steady_operating_curve(BENCHMARK, [v], f * p_avail)[1][0]) for f in (1.0, 0.8, 0.5)]
        print(f"  {v:5.1f} m/s ({p_avail / 1e6:.2f} MW): " + " / ".join(f"{c:.3f}" for c in cts))


if __name__ == "__main__":
    main()
