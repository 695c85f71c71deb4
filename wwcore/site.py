"""What a supervisor may learn of the site it supervises: ``SiteInfo``.

The plant publishes its nominal parameters, the turbine numbers of its rows, its sensors' noise, its sample time and
(a farm) its layout. It never publishes what only the simulator knows: the fault schedule, the wind, a model
mismatch, the farm's wind case or direction (a detector estimates it, or is told it through its own options). Each
scenario section builds its site (``TurbinePlant.site``, ``FarmPlant.site``, ``HydroPlant.site``); a live supervisor
is built from it and the supervisor's algorithms alone (``windwarden.kinds``). Over the network it travels inside the
``plant.run`` message, validated on arrival: an unknown field (a ``mismatch`` or a fault sneaked in) is refused.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

NoiseConvention = Literal["sigma", "variance"]


class SiteInfo(BaseModel):
    """The published parameters of a plant, one frozen object (the same in batch, lockstep and realtime)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: Literal["turbine", "farm", "hydro"]
    turbines: tuple[int, ...] = Field(min_length=1, description="the site's turbine numbers")
    dt: float = Field(gt=0.0, description="s, the plant's sample time (one tick)")
    rated_power_w: float | None = Field(default=None, gt=0.0, description="W, rated power of one turbine")
    noise_convention: NoiseConvention = Field(
        default="sigma", description="how the benchmark's sensor noise numbers read: as σ or as variances"
    )
    sensor_sigma: dict[str, float] = Field(
        default_factory=dict, description="σ of each sensor channel's noise under the convention, in its unit"
    )
    positions_m: tuple[tuple[float, float], ...] = Field(
        default=(),
        description="farm: (x east, y north) in m of turbines 1 … n, the resolved layout; empty for a single turbine",
    )
    spacing_m: float | None = Field(
        default=None, gt=0.0, description="farm: m, grid spacing (a layout's: the smallest distance between turbines)"
    )
    rotor_diameter_m: float | None = Field(default=None, gt=0.0, description="farm: m, rotor diameter D")
    mast_distance_m: float | None = Field(default=None, ge=0.0, description="farm: m, met mast upwind of the front row")
    stroke_max: float | None = Field(
        default=None, gt=0.0, description="hydro: –, mechanical stop of both displacement units"
    )
