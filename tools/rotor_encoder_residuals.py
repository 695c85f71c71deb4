"""Each rotor-speed sensor against one generator-speed sensor through the gear, on healthy runs at constant mean
winds (docs/turbine.md, "Against one encoder"): e_s = (y_rs − y_gk/N_g)/σ_e with the supervisor's calibrated
readings, per reference (observer 4's encoder mean, ω_g,m1, ω_g,m2). Printed per wind: the variances of e_1 and
e_2, their covariance, ρ₁ and ρ₁₀ of e_1, the variance per tick of k-tick sums, the information a bias on ω_r,m1
carries per tick (the sums' 2 × 2 covariance inverted) over the pair's 1/2, and the twist rate ω_r − ω_g/N_g's std,
all in σ_e. The scenario is ``turbine-fault-free``'s wind (turbulence, shear, tower shadow) at one mean; with
``--mismatch`` the plant of ``ftwse-2012-mismatch``.

    nice -n 5 .venv/bin/python tools/rotor_encoder_residuals.py --winds 4,6,8,10,11.5,13,16,20,25 --runs 6 \\
        --duration 200 --seed 11
    nice -n 5 .venv/bin/python tools/rotor_encoder_residuals.py --winds 6,11.5,13,16 --runs 6 --duration 200 \\
        --seed 12 --mismatch
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from plant_sim.turbine.plant import OMEGA_G, OMEGA_R
from windwarden.evaluation.turbine import batch_and_supervisor
from wwcore.scenario import load_scenario
from wwcore.stepping import run_ticks

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
WARMUP_S = 30.0
SUMS = (1, 6, 10, 20)


def _scenario(wind: float, duration: float, mismatch: bool) -> str:
    """``turbine-fault-free`` at a constant mean ``wind`` for ``duration`` s (and the mismatch section), as a file."""
    head, rest = (SCENARIOS / "turbine-fault-free.toml").read_text().split("[wind]", 1)
    head = head.replace("duration_s = 4400.0", f"duration_s = {duration}")
    lines, skipping = [], False
    for line in rest.split("\n"):
        if line.startswith("mean ="):
            lines.append(f"mean = [[0.0, {wind}], [{duration}, {wind}]]")
            skipping = True
        elif not (skipping and line.startswith(" ")):
            skipping = False
            lines.append(line)
    text = head + "[wind]" + "\n".join(lines)
    if mismatch:
        text += "\n[mismatch]" + (SCENARIOS / "ftwse-2012-mismatch.toml").read_text().split("[mismatch]", 1)[1]
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(text)
    return f.name


def measure(wind: float, runs: int, duration: float, mismatch: bool, seed: int) -> dict:
    scenario = load_scenario(_scenario(wind, duration, mismatch))
    plant, supervisor = batch_and_supervisor(
        scenario, seed, list(range(runs)), options=dict(scenario.supervisor.params)
    )
    fdi = supervisor.detector.fdi
    gear, sigma_e = fdi._gear_ratio, fdi.arbiter.encoder_sigma
    readings, twist = [], []

    def record(k: int, frame, refs) -> None:
        y = supervisor.detector.context.speed_readings(frame)
        readings.append(y - fdi.calibration.offset if fdi.calibration.enabled else y.copy())
        twist.append(plant.x[:, OMEGA_R] - plant.x[:, OMEGA_G] / gear)

    run_ticks(plant, supervisor, range(round(duration / plant.dt)), stepped=record)
    first = round(WARMUP_S / plant.dt)
    y = np.array(readings)[first:]  # (T, n, 4)
    references = {"4": 0.5 * (y[..., 2] + y[..., 3]), "g1": y[..., 2], "g2": y[..., 3]}
    out = {"twist": float(np.array(twist)[first:].std() / sigma_e)}
    for name, reference in references.items():
        e = (y[..., :2] - reference[..., None] / gear) / sigma_e
        e = e - e.mean(axis=0)  # per run: a calibration offset left over is not the question here
        row = {
            "var": (float(e[..., 0].var()), float(e[..., 1].var())),
            "cov": float((e[..., 0] * e[..., 1]).mean()),
            "rho": tuple(float((e[k:, :, 0] * e[:-k, :, 0]).mean() / e[..., 0].var()) for k in (1, 10)),
        }
        for k in SUMS:
            m = e.shape[0] // k
            sums = e[: m * k].reshape(m, k, *e.shape[1:]).sum(axis=1).reshape(-1, 2)
            covariance = np.cov(sums.T) / k
            row[f"sum_var{k}"] = float(covariance[0, 0])
            row[f"info{k}"] = float(np.linalg.solve(covariance, [1.0, 0.0])[0]) / 0.5
        out[name] = row
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--winds", default="6,11.5,13,16")
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--duration", type=float, default=200.0)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--mismatch", action="store_true")
    args = parser.parse_args(argv)
    print("wind  ref  var e1/e2    cov     rho1    rho10  | var of k-sums/k, k = " + " ".join(map(str, SUMS))
          + " | info / pair's, same k | twist rate std (σ_e)")  # fmt: skip
    for wind in (float(w) for w in args.winds.split(",")):
        r = measure(wind, args.runs, args.duration, args.mismatch, args.seed)
        for name in ("4", "g1", "g2"):
            x = r[name]
            sums = " ".join(f"{x[f'sum_var{k}']:.3f}" for k in SUMS)
            info = " ".join(f"{x[f'info{k}']:.2f}" for k in SUMS)
            print(f"{wind:5.1f} {name:>3}  {x['var'][0]:.3f}/{x['var'][1]:.3f}  {x['cov']:+.3f}  {x['rho'][0]:+.3f}  "
                  f"{x['rho'][1]:+.3f}  | {sums} | {info} | {r['twist']:.3f}", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
