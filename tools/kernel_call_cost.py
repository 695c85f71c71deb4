"""What one turbine run's kernel calls cost in their arguments: ``windwarden bench turbine``'s plant and supervisor
for ``ftwse-2012`` on the compiled backend, warmed up; one tick's arguments of each kernel named are captured, then
timed (best of ``--repeat`` blocks of ``--calls`` calls, µs of CPU time a call): the kernel itself on copies of them
(each call does the captured tick's work, on arrays out of the caches), the kernel on one copy again and again (its
arrays in the caches, as a tick's are nearer to), and an empty ``njit`` function taking the same arguments (what the
dispatcher's type check and unboxing cost). The arrays a call unboxes are counted through its tuples; a
``wwcore.kept.Kept`` (the kept arguments as one struct: the ``_kept`` entry points) counts as one struct, the
arrays it holds apart.

    .venv/bin/python tools/kernel_call_cost.py
"""

from __future__ import annotations

import argparse
import copy
import time

import numba
import numpy as np

from windwarden.bench import _Stepper, turbine_pair
from wwcore.backend import fast_module
from wwcore.kept import Kept

KERNELS = (
    ("service.turbine.fast_detector", "detector_tick"),
    ("service.turbine.fast_detector", "detector_tick_kept"),
    ("service.turbine.fast", "component_step"),
    ("service.turbine.fast", "component_step_kept"),
    ("service.turbine.fast", "bank_tick"),
    ("service.turbine.fast", "bank_tick_kept"),
    ("plant_sim.turbine.fast", "measure"),
)


def arrays(value) -> int:
    """The arrays in ``value``, through nested tuples (not those a struct holds)."""
    if isinstance(value, np.ndarray):
        return 1
    if isinstance(value, tuple):
        return sum(arrays(v) for v in value)
    return 0


def structs(value) -> tuple[int, int]:
    """The ``Kept`` structs in ``value``, through nested tuples, and the arrays they hold."""
    if isinstance(value, Kept):
        return 1, arrays(value.args)
    if isinstance(value, tuple):
        counts = [structs(v) for v in value] or [(0, 0)]
        return tuple(int(sum(c)) for c in zip(*counts, strict=True))
    return 0, 0


def empty_kernel(arity: int):
    """An ``njit`` function of ``arity`` arguments that does nothing."""
    names = ", ".join(f"a{i}" for i in range(arity))
    scope: dict = {}
    exec(f"def empty({names}):\n    return 0\n", scope)  # a measurement's empty function
    return numba.njit(scope["empty"])


def best(call, calls: int, repeat: int) -> float:
    """Best of ``repeat`` blocks of ``calls`` calls of ``call(i)``, µs of CPU time a call."""
    times = []
    for _ in range(repeat):
        start = time.process_time()
        for i in range(calls):
            call(i)
        times.append((time.process_time() - start) / calls)
    return 1e6 * min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=1, help="runs stepped side by side")
    parser.add_argument("--warmup", type=int, default=800, help="ticks run before the arguments are captured")
    parser.add_argument("--calls", type=int, default=300, help="calls in a timed block")
    parser.add_argument("--repeat", type=int, default=7, help="timed blocks; the best is printed")
    args = parser.parse_args()
    plant, supervisor = turbine_pair("ftwse-2012", args.rows, 0, False, "numba")
    stepper = _Stepper(plant, supervisor)
    stepper.run(args.warmup)
    print("| kernel | arrays unboxed (+ structs: their arrays) | the kernel, µs a call | on one copy | empty njit |")
    print("|---|---|---|---|---|")
    for module, name in KERNELS:
        kernels = fast_module(module)
        real = getattr(kernels, name, None)
        if real is None:
            print(f"| `{name}` | not in this tree | | | |")
            continue
        captured: list = []

        def capture(*call_args, _real=real, _captured=captured):
            if not _captured:
                _captured.append(copy.deepcopy(call_args))
            return _real(*call_args)

        setattr(kernels, name, capture)
        try:
            stepper.run(1)
        finally:
            setattr(kernels, name, real)
        if not captured:
            print(f"| `{name}` | not called | | | |")
            continue
        call_args = captured[0]
        copies = [copy.deepcopy(call_args) for _ in range(args.calls * args.repeat)]
        empty = empty_kernel(len(call_args))
        empty(*call_args)  # compiled here, not timed
        # each copy once: every call does the captured tick's work
        real_us = best(lambda i, f=real, c=copies: f(*c.pop()), args.calls, args.repeat)
        hot = copy.deepcopy(call_args)
        hot_us = best(lambda i, f=real, a=hot: f(*a), args.calls, args.repeat)
        empty_us = best(lambda i, f=empty, a=call_args: f(*a), args.calls, args.repeat)
        packed, held = structs(call_args)
        unboxed = f"{arrays(call_args)}" + (f" + {packed}: {held}" if packed else "")
        print(f"| `{name}` | {unboxed} | {real_us:.1f} | {hot_us:.1f} | {empty_us:.1f} |")


if __name__ == "__main__":
    main()
