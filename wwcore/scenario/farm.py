"""Plant section of a wind-farm scenario (seed 001). Filled in by the farm work."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict

from wwcore.scenario.faults import FaultSpec


class FarmPlant(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["farm"] = "farm"

    @property
    def n_turbines(self) -> int:
        return 9


def check_farm_fault(fault: FaultSpec, n_turbines: int) -> list[tuple[str, str]]:
    return [("target", "farm faults are not available yet")]
