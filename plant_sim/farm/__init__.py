"""The nine-turbine wind farm of seed 001 (PARAMETERS.md b): wind field, turbine controller, batch plant, damage."""

from plant_sim.farm.plant import FarmBatch

__all__ = ["FarmBatch"]
