"""The scenario: everything one run needs, read from a TOML file and validated before anything runs."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from wwcore.scenario.farm import N_TURBINES, FarmPlant, check_farm_fault
from wwcore.scenario.faults import FaultSpec
from wwcore.scenario.hydro import HydroPlant, check_hydro_fault
from wwcore.scenario.mismatch import Mismatch
from wwcore.scenario.turbine import TurbinePlant, check_turbine_fault
from wwcore.scenario.wind import WindSpec

PlantSpec = Annotated[TurbinePlant | FarmPlant | HydroPlant, Field(discriminator="kind")]

FAULT_CHECKS: dict[str, Callable[[FaultSpec, int], list[tuple[str, str]]]] = {
    "turbine": check_turbine_fault,
    "farm": check_farm_fault,
    "hydro": check_hydro_fault,
}
"""Per plant kind: the rules a fault must follow beyond its schema (targets, kinds, physical ranges)."""

SUPERVISOR_ROLES: dict[str, tuple[str, ...]] = {
    "turbine": ("detector", "estimator"),
    "farm": ("detector", "controller"),
    "hydro": ("detector", "estimator"),
}
"""Per plant kind, the ``[supervisor]`` roles its supervisor has (``service.plugins.ROLES`` maps them to registries).
A role the kind does not have is refused at load; the names and ``params`` are checked against the registries'
declared options by ``service.plugins.choose`` before anything runs."""


class SupervisorSpec(BaseModel):
    """Which registered algorithms the supervisor runs, by name (see ``service.plugins``)."""

    model_config = ConfigDict(extra="forbid")

    detector: str | None = Field(default=None, description="fault detector; None picks the plant kind's default")
    estimator: str | None = Field(
        default=None, description="turbine estimator or hydrostatic observer; None picks the default"
    )
    controller: str | None = Field(default=None, description="farm controller; None picks the default")
    params: dict[str, Any] = Field(
        default_factory=dict, description="options of the selected algorithms, each declared by one of them"
    )


class Scenario(BaseModel):
    """One scenario file. Unknown keys are refused everywhere."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(min_length=1, max_length=80, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")
    description: str = ""
    duration_s: float = Field(gt=0.0, le=100_000.0, description="s of simulated time")
    plant: PlantSpec
    wind: WindSpec = Field(default_factory=WindSpec)
    supervisor: SupervisorSpec = Field(default_factory=SupervisorSpec)
    faults: list[FaultSpec] = Field(default_factory=list)
    mismatch: Mismatch | None = Field(
        default=None, description="how the plant differs from the supervisor's design model; the plant alone reads it"
    )

    def problems(self) -> list[tuple[str, str]]:
        """Checks that need the whole scenario, as (field path, message) pairs; empty when it is valid."""
        found: list[tuple[str, str]] = []
        roles = SUPERVISOR_ROLES[self.plant.kind]
        for role in ("detector", "estimator", "controller"):
            if getattr(self.supervisor, role) is not None and role not in roles:
                found.append(
                    (
                        f"supervisor.{role}",
                        f"a {self.plant.kind} supervisor has no {role}; its roles: {', '.join(roles)}",
                    )
                )
        if isinstance(self.plant, FarmPlant) and not self.plant.is_paper_farm():
            for key in ("wind_case",):  # what the supervisor cannot do on this farm
                if key in self.supervisor.params:
                    found.append(
                        (
                            f"supervisor.params.{key}",
                            f"the wind cases 1 and 2 are directions on seed 001's {N_TURBINES} turbines (its 3 × 3); "
                            f"this farm has {self.plant.n_turbines} turbines with wind from "
                            f"{self.plant.direction_deg:g} deg: give wind_direction_deg, or let the paper detector "
                            "read the mast's vane",
                        )
                    )
        check = FAULT_CHECKS[self.plant.kind]
        for i, fault in enumerate(self.faults):
            for field, message in check(fault, self.plant.n_turbines):
                found.append((f"faults[{i}].{field}", message))
            if fault.start_s >= self.duration_s:
                found.append((f"faults[{i}].start_s", f"{fault.start_s} s is after the run ends ({self.duration_s} s)"))
        if self.mismatch is not None:
            if self.plant.kind == "hydro":
                found.append(
                    (
                        "mismatch",
                        "the hydrostatic plant takes its uncertainties in [plant] (leak_factor, "
                        "delta_cq, noise_pct); [mismatch] is for the turbine and the farm",
                    )
                )
            else:
                found += self.mismatch.problems(self.plant.n_turbines)
        labels = [f.label for f in self.faults]
        for i, label in enumerate(labels):
            if label in labels[:i]:
                found.append((f"faults[{i}].name", f"two faults share the label {label!r}; give them names"))
        return found
