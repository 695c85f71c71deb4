"""The 4.8 MW benchmark turbine (PARAMETERS.md a), vectorised over a batch of independent turbines."""

from plant_sim.turbine.plant import TurbineBatch

__all__ = ["TurbineBatch"]
