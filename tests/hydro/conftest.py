"""Shared helpers of the hydrostatic tests: short batch simulations of plant and supervisor."""

from __future__ import annotations

import numpy as np
import pytest

from plant_sim.hydro import HydroTurbineBatch
from service.hydro.supervisor import HydroSupervisor
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.scenario.hydro import HydroPlant
from wwcore.scenario.wind import WindSpec

WIND = WindSpec(mean=[(0.0, 7.5)], turbulence_intensity=0.15, length_scale_m=340.0)


def offset(target: str, value: float, start: float, end: float | None, name: str | None = None) -> FaultSpec:
    return FaultSpec(target=target, kind=FaultKind.OFFSET, value=value, start_s=start, end_s=end, name=name)


def run_loop(plant: HydroTurbineBatch, supervisor: HydroSupervisor | None, seconds: float) -> dict[str, np.ndarray]:
    """Step plant (and supervisor) for ``seconds``; traces (ticks, runs, …) of states, faults and refs."""
    xs, fs, corr, fhat = [], [], [], []
    refs = None
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        if supervisor is not None:
            refs = supervisor.step(frame)
            corr.append(refs.correction.copy())
            fhat.append(refs.f_hat.copy())
        truth = plant.truth()
        xs.append(truth["x"])
        fs.append(truth["f"])
        plant.advance()
    out = {"x": np.array(xs), "f": np.array(fs)}
    if supervisor is not None:
        out["f_filt"] = np.array(corr)
        out["f_hat"] = np.array(fhat)
    return out


@pytest.fixture
def make_plant():
    def make(faults=(), n=2, seed=3, **plant_options) -> HydroTurbineBatch:
        seeds = [np.random.SeedSequence(seed, spawn_key=(0, i)) for i in range(n)]
        return HydroTurbineBatch(HydroPlant(**plant_options), WIND, list(faults), seeds)

    return make
