"""The wind turbine with hydrostatic transmission of seed 003: wind, baseline controller, batch plant."""

from plant_sim.hydro.controller import BaselineController
from plant_sim.hydro.plant import HydroTurbineBatch
from plant_sim.hydro.wind import HydroWind

__all__ = ["BaselineController", "HydroTurbineBatch", "HydroWind"]
