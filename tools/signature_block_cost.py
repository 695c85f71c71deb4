"""What the pitch-actuator signature bank's kernel costs alone, per row count: ``fast_actuator.signature_block`` on the
real bank's matrices (a numpy supervisor's ``SignatureBank``, its state after one block of ramps) with this machine's
``numpy_matmul_order``, one block of 10 ticks a call, the best of five blocks of calls, µs of CPU time a call.

    .venv/bin/python tools/signature_block_cost.py --rows 1,7,8,9,50,225
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from service.turbine.supervisor import TurbineSupervisor
from wwcore.backend import fast_module


def block_cost(n: int, order: int, kernel) -> float:
    """µs of CPU time of one ``signature_block`` call on n rows (best of five blocks of calls)."""
    components = TurbineSupervisor(n, backend="numpy").detector.components
    bank, ticks = components.signatures, components._ref_block.shape[0]
    rng = np.random.default_rng(1)
    reference = 6.0 + np.cumsum(rng.normal(0.0, 0.5, (ticks, n)), axis=0)
    w = rng.normal(0.0, 1.0, (ticks, n, 3))
    bank.block(reference)
    k = len(bank.candidates)
    sums = (np.empty((n, 3, k)), np.empty((n, k)), np.empty((n, 3 + k)))
    arguments = (reference, bank.x, bank._At, bank._B, bank._C, bank._D, w, *sums, order)
    return call_cost(kernel, arguments, max(20, 20_000 // n))


def call_cost(kernel, arguments: tuple, calls: int) -> float:
    """µs of CPU time of one ``kernel(*arguments)`` (after one call), the best of five blocks of ``calls`` calls."""
    kernel(*arguments)
    best = []
    for _ in range(5):
        start = time.process_time()
        for _ in range(calls):
            kernel(*arguments)
        best.append((time.process_time() - start) / calls * 1e6)
    return min(best)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="1,7,8,9,50,225", help="row counts, comma-separated")
    args = parser.parse_args()
    fast_actuator = fast_module("service.turbine.fast_actuator")
    order = fast_actuator.numpy_matmul_order()
    costs = [(int(n), block_cost(int(n), order, fast_actuator.signature_block)) for n in args.rows.split(",")]
    print(f"order {order}: " + "  ".join(f"{n} rows {cost:.1f} µs" for n, cost in costs))


if __name__ == "__main__":
    main()
