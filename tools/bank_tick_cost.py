"""What the observer bank's kept tick costs alone, per row count: ``fast_bank.bank_tick_kept`` on arguments captured
from the benchmark turbine's batch (``windwarden.bench.turbine_pair("ftwse-2012", …, "numba")``: 2 × runs rows with
fault-free twins for even counts, else runs rows alone) after ``--ticks`` ticks, the best of five blocks of calls,
µs of CPU time a call.

    .venv/bin/python tools/bank_tick_cost.py --rows 1,8,50,225 --ticks 600
"""

from __future__ import annotations

import argparse

import numpy as np
from signature_block_cost import call_cost  # this directory's, run as a script

from windwarden.bench import _Stepper, turbine_pair


def captured(n: int, ticks: int) -> tuple:
    """``bank_tick_kept`` and its arguments as ``ObserverBank.step_readings`` makes them for the next frame of an
    n-row batch run ``ticks`` ticks (the one-row batch's supervisor makes the same call from its one-call tick)."""
    twins = n % 2 == 0 and n > 1
    plant, supervisor = turbine_pair("ftwse-2012", n // 2 if twins else n, 0, twins, "numba")
    _Stepper(plant, supervisor).run(ticks)
    context = supervisor.context
    bank, frame = context._bank, plant.measure()
    inputs, offset = context._input_columns(frame), context.speed_offset
    read, chi2 = np.empty((n, 6)), np.empty((n, len(bank.d.names)))
    speed = np.empty((n, 4)) if offset is not None else read[:, :4]
    subtract, offset = offset is not None, speed if offset is None else offset
    if bank.kept is None:
        update, sparse = bank._fast_products(True)
        bank.kept = bank._fast.Kept((*inputs[1:], update, bank._output, bank._work, sparse))
    arguments = (inputs[0], subtract, offset, speed, read, bank.z, frame.tau_g_ref, bank._y_prev, chi2, bank.kept)
    return bank._fast.bank_tick_kept, arguments


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="1,8,50,225", help="row counts, comma-separated")
    parser.add_argument("--ticks", type=int, default=600, help="ticks run before the captured call")
    args = parser.parse_args()
    rows = [int(n) for n in args.rows.split(",")]
    costs = [(n, call_cost(*captured(n, args.ticks), max(200, 200_000 // n))) for n in rows]
    print("  ".join(f"{n} rows {cost:.2f} µs" for n, cost in costs))


if __name__ == "__main__":
    main()
