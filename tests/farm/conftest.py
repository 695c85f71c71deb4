"""Shared helpers of the farm tests: short batch simulations of the farm and its supervisor."""

from __future__ import annotations

import numpy as np

from plant_sim.farm import FarmBatch
from service.farm.supervisor import FarmSupervisor
from wwcore.scenario.farm import FarmDemand, FarmPlant
from wwcore.scenario.faults import FaultSpec
from wwcore.scenario.wind import WindSpec


def farm_spec(case: int = 1, **kw) -> FarmPlant:
    return FarmPlant(wind_case=case, demand=FarmDemand(mode="available_fraction", fraction=0.8, update_s=10.0), **kw)


def wind(speed: float, ti: float = 0.10) -> WindSpec:
    return WindSpec(mean=[(0.0, speed)], turbulence_intensity=ti)


def simulate(
    plant_spec: FarmPlant,
    wind_spec: WindSpec,
    faults: list[FaultSpec],
    seconds: float,
    *,
    seed: int = 3,
    runs: tuple[int, ...] = (0,),
    detector: str = "analytic",
    controller: str = "dispatch",
    twins: bool = False,
    options: dict | None = None,
) -> tuple[FarmBatch, FarmSupervisor, list]:
    """Run plant + supervisor for ``seconds``; returns them and all supervisor events."""
    plant = FarmBatch(plant_spec, wind_spec, faults, seed=seed, duration_s=seconds, runs=runs, fault_free_twins=twins)
    sup = FarmSupervisor(plant_spec.site(), plant.n, detector=detector, controller=controller, options=options)
    refs = None
    events = []
    for _ in range(round(seconds / plant.dt)):
        frame = plant.measure()
        plant.control(refs)
        refs = sup.step(frame)
        plant.advance()
    events += sup.drain_events()
    return plant, sup, events


def detections(events: list, target: str | None = None) -> list:
    return [e for e in events if e.type.value == "detection" and (target is None or e.target == target)]


def as_array(values) -> np.ndarray:
    return np.asarray(values, dtype=float)
