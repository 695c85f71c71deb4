"""Plant section of a hydrostatic-transmission turbine scenario (seed 003). Filled in by the hydro work."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict

from wwcore.scenario.faults import FaultSpec


class HydroPlant(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["hydro"] = "hydro"

    @property
    def n_turbines(self) -> int:
        return 1


def check_hydro_fault(fault: FaultSpec, n_turbines: int) -> list[tuple[str, str]]:
    return [("target", "hydrostatic faults are not available yet")]
