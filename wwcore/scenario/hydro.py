"""Plant section of a hydrostatic-transmission turbine scenario (seed 003) and the rules its faults follow.

The wind comes from the scenario's top-level ``[wind]`` section (mean points, turbulence intensity, length
scale; shear and tower shadow do not apply to the rotor-effective wind of this model and are ignored).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from wwcore.hydro_params import FAULT_TARGETS, NOMINAL
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.site import SiteInfo

OFFSET_LIMIT = 1.0
"""Largest |offset| on a normalised displacement command: a full stroke."""


class HydroPlant(BaseModel):
    """The turbine with hydrostatic transmission of seed 003 (PARAMETERS.md c), with the paper's uncertainties."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["hydro"] = "hydro"
    leak_factor: float = Field(
        default=1.0,
        ge=0.5,
        le=3.0,
        description="–, k_leak of the plant / k_leak,n of the observer and controller, eq. (16); paper: 1.15",
    )
    delta_cq: float = Field(
        default=0.0, ge=-0.5, le=0.5, description="–, aerodynamic uncertainty δ_CQ of eq. (17); paper: 0.2"
    )
    noise_pct: float = Field(
        default=0.1,
        ge=0.0,
        le=10.0,
        description="%, measurement noise: each reading is multiplied by 1 + ε, ε uniform in ±noise_pct/100; "
        "paper's noise case: 2",
    )
    stroke_max: float = Field(
        default=1.5,
        ge=1.0,
        le=2.0,
        description="–, mechanical stop of both displacement units (x̃ = 1 is the rated stroke); see docs/hydro.md",
    )

    @property
    def n_turbines(self) -> int:
        return 1

    def site(self, dt: float = NOMINAL.dt) -> SiteInfo:
        """What the supervisor may know: the nominal model (``hydro_params.NOMINAL``) with this stroke limit. The
        leakage factor and the aerodynamic uncertainty are the plant's secret (the observer's uncertainty)."""
        return SiteInfo(kind="hydro", turbines=(1,), dt=float(dt), stroke_max=self.stroke_max)


def check_hydro_fault(fault: FaultSpec, n_turbines: int) -> list[tuple[str, str]]:
    """Problems with one fault on the hydrostatic turbine, as (field, message) pairs; empty when it is valid.

    Only additive offsets on the pump and motor displacement commands (u_p, u_M) exist in this plant, sized in
    normalised stroke units, nonzero and at most a full stroke.
    """
    problems: list[tuple[str, str]] = []
    if fault.turbine > n_turbines:
        problems.append(("turbine", f"turbine {fault.turbine} does not exist (the plant has {n_turbines})"))
    if fault.target not in FAULT_TARGETS:
        problems.append(
            ("target", f"unknown actuator {fault.target!r}; a hydrostatic fault hits one of {list(FAULT_TARGETS)}")
        )
    if fault.kind is not FaultKind.OFFSET:
        problems.append(("kind", f"{fault.kind.value!r} is not available here; use 'offset' on u_p or u_M"))
    if fault.value is None:
        problems.append(("value", "an offset fault needs a value (normalised displacement, −1 … 1)"))
    elif not -OFFSET_LIMIT <= fault.value <= OFFSET_LIMIT:
        problems.append(("value", f"{fault.value} is outside the physical range −1 … 1 (normalised displacement)"))
    elif fault.value == 0.0:
        problems.append(("value", "an offset of 0 is no fault"))
    return problems
