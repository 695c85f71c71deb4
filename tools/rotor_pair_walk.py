"""The sequential tests that decide a generator-speed explanation's rotor-speed half, simulated on white noise
(docs/turbine.md, "Against one encoder"; docs/decisions.md N-21, N-23): mean ticks to a decision on a healthy pair
(and how often a rotor-speed sensor joins there), and the share of "both healthy" decisions (partial first flags)
beside a bias on one rotor-speed sensor, for N-16's test of the pair's difference and for the test of each
rotor-speed sensor against one encoder. Decisions no earlier than the 3rd tick, at most ``arbitration_s`` = 5 s.

    .venv/bin/python tools/rotor_pair_walk.py --rows 100000 --seed 5
"""

from __future__ import annotations

import argparse
import math

import numpy as np

ISO, CONFIRM, PATIENCE, FIRST = 1e-3, 0.05, 500, 3
BIASES = (0.0, 0.7, 0.87, 1.0, 1.25, 1.5)  # σ_r on one rotor-speed sensor


def walk(rng: np.random.Generator, mu: float, m: float, rows: int, pair: bool) -> tuple[np.ndarray, np.ndarray]:
    """Each row's decision (+1 join, −1 both healthy, 0 none) and its tick. ``pair``: Λ = m_d|Σd| − k m_d²/2 with
    d = (e_1 − e_2)/√2, m_d = m/√2, joining at ln(2/α_iso); else Λ_s = m|Σe_s| − k m²/2, joining at ln(4/α_iso)."""
    sums = np.zeros((rows, 2))
    decision, tick = np.zeros(rows, dtype=int), np.zeros(rows, dtype=int)
    join = math.log((2.0 if pair else 4.0) / ISO)
    for k in range(1, PATIENCE + 1):
        live = decision == 0
        if not live.any():
            break
        sums[live] += rng.standard_normal((int(live.sum()), 2)) + np.array([mu, 0.0])
        if pair:
            shift = m / math.sqrt(2.0)
            evidence = shift * np.abs(sums[:, 0] - sums[:, 1]) / math.sqrt(2.0) - k * shift**2 / 2.0
        else:
            evidence = (m * np.abs(sums) - k * m**2 / 2.0).max(axis=1)
        if k >= FIRST:
            joined = live & (evidence >= join)
            healthy = live & (evidence <= -math.log(1.0 / CONFIRM)) & ~joined
            decision[joined], decision[healthy] = 1, -1
            tick[joined | healthy] = k
    return decision, tick


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print("test          m (σ_r)  healthy: ticks, joins %  | partial first flags % beside " + " / ".join(
        f"{b} σ_r" for b in BIASES[1:]))  # fmt: skip
    for pair, m in ((True, 1.5), (False, 1.5), (False, 1.3), (False, 1.25), (False, 1.2), (False, 1.06)):
        decision, tick = walk(rng, 0.0, m, args.rows, pair)
        cells = [f"{tick.mean():5.2f}, {100 * (decision == 1).mean():.3f}"]
        for bias in BIASES[1:]:
            decision, _ = walk(rng, bias, m, args.rows, pair)
            cells.append(f"{100 * (decision == -1).mean():5.1f}")
        print(f"{'pair' if pair else 'one encoder':12s}  {m:5.2f}    " + "  ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
