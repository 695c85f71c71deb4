"""Benchmark of the hydrostatic observer step and of a batch evaluation's simulation loop.

Reports, for 1 run and for 20 runs in one batch: observer steps per second (one step = one 10 ms sample,
integrated with N forward-Euler substeps, see ``service.hydro.smo``) and simulated seconds per wall second of
the observer alone and of plant + controller + observer + supervisor (the loop ``windwarden eval`` runs).

    .venv/bin/python tools/bench_hydro.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from plant_sim.hydro import HydroTurbineBatch
from service.hydro.smo import TSSlidingModeObserver
from service.hydro.supervisor import HydroSupervisor
from wwcore.hydro_model import equilibrium
from wwcore.hydro_params import NOMINAL
from wwcore.scenario import load_scenario
from wwcore.stepping import run_ticks


def bench_observer(n: int, steps: int) -> float:
    """Observer steps per second for a batch of n turbines (measurements and commands held)."""
    obs = TSSlidingModeObserver(NOMINAL, n)
    eq = equilibrium(np.full(n, 7.5), NOMINAL)
    y, u = eq.x[:, [0, 1, 3, 4, 5]], eq.u
    obs.step(y, u)
    t0 = time.perf_counter()
    for _ in range(steps):
        obs.step(y, u)
    return steps / (time.perf_counter() - t0)


def bench_loop(n: int, seconds: float) -> float:
    """Simulated seconds per wall second of the full batch loop for hydro-fig9 with n runs."""
    scenario = load_scenario("hydro-fig9")
    seeds = [np.random.SeedSequence(0, spawn_key=(0, i)) for i in range(n)]
    plant = HydroTurbineBatch(scenario.plant, scenario.wind, list(scenario.faults), seeds)
    sup = HydroSupervisor(n=n, params=plant.nominal, options=scenario.supervisor.params)
    t0 = time.perf_counter()
    run_ticks(plant, sup, range(round(seconds / plant.dt)))
    return seconds / (time.perf_counter() - t0)


def main(seconds: float = 20.0) -> None:
    probe = TSSlidingModeObserver(NOMINAL, 1)
    d = probe.design
    print(
        f"observer: dt = {NOMINAL.dt * 1e3:g} ms, {d.substeps} substeps of {NOMINAL.dt / d.substeps * 1e3:.3f} ms "
        f"(boundary-layer gain ρλmax(P2)/δ = {d.settings.rho * np.linalg.eigvalsh(d.P2).max() / d.settings.delta:g}"
        " 1/s)"
    )
    steps = round(seconds / NOMINAL.dt)
    for n in (1, 20):
        rate = bench_observer(n, steps)
        print(
            f"{n:>2} run(s): observer {rate:8.0f} steps/s = {rate * NOMINAL.dt:6.1f} simulated s per wall s "
            f"({rate * NOMINAL.dt * n:6.1f} run-s/s)"
        )
        loop = bench_loop(n, seconds)
        print(f"{n:>2} run(s): plant + supervisor loop {loop:6.1f} simulated s per wall s ({loop * n:6.1f} run-s/s)")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per measurement")
    main(parser.parse_args().seconds)
