"""Plant section of a wind-farm scenario (seed 001, PARAMETERS.md b), its geometry, and the rules its faults follow.

The farm is nine benchmark turbines on a 3 × 3 grid numbered row by row (1 2 3 / 4 5 6 / 7 8 9), spacing
``spacing_m`` in both directions. The wind comes from one of two directions (the paper's two wind cases):

* case 1, along the grid lines: the rows facing the wind are {1, 4, 7}, {2, 5, 8}, {3, 6, 9};
* case 2, along the diagonal: the rows are {1}, {2, 4}, {3, 5, 7}, {6, 8}, {9} (turbines 1 and 9 stand alone).

A row is a set of turbines at the same distance along the wind. The met mast stands ``mast_distance_m`` upwind
of the front row, on the wind axis, in both cases.

``wake_model`` picks the wakes: FLORIS's ``gauss`` (the default) or ``jensen`` between every pair of turbines
(``plant_sim.farm.wakes``), or ``rows``, the paper's row model (3 × 3, its two wind cases only). With a FLORIS model
the farm may also have any ``layout`` (``wwcore.layout``: a grid, coordinates or a shipped file, 1 to 250
turbines) and any constant ``wind_direction_deg``, or a direction that moves: ``wind_direction_profile`` plus a
slow random veer (``veer_sigma_deg``, ``veer_time_s``; ``plant_sim.farm.direction``). The supervisor
(``service.farm``) learns the layout from ``site()`` (turbine numbers and positions) and handles any of them.

The scenario's top-level ``[wind]`` section describes the free stream at the mast (mean profile) and each
turbine's own turbulence (``turbulence_intensity``); the farm adds a slow turbulence common to all turbines
(``coherent_ti``, ``coherent_time_s``) that travels from the mast to each row (``docs/farm.md``).

Farm faults name their turbine with ``turbine`` (1–9); target and kind say what they do:

===================  =================  =======================================================  ============
target               kind               effect (value)                                           scorecard
===================  =================  =======================================================  ============
``rotor``            ``debris``         power output × value at unchanged rotor speed (0.97)     ``debris``
``pitch_actuator_k`` ``offset``         blade k held value deg off the collective command;       ``pitch_misalignment``
                                        its pitch encoders see the true angle (0.3)
``pitch_actuator_k`` ``pitch_offset``   blade k's aerodynamic angle off by value deg, unseen by  ``pitch_misalignment``
                                        its encoders (a hidden mounting error)
``drivetrain``       ``drivetrain_wear`` planet-pass (3P) transmission error of amplitude value   ``drivetrain``
                                        mrad on the low-speed shaft (5)
===================  =================  =======================================================  ============

Any fault a single benchmark turbine accepts (sensor faults, pitch dynamics, converter offset, efficiency) is
accepted on a farm turbine too (``check_turbine_fault``). Why the farm faults are modelled this way is in
``docs/farm.md`` (and next to the code in ``plant_sim.turbine.faults``).
"""

from __future__ import annotations

import itertools
import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from wwcore.layout import SEED001_DIRECTIONS_DEG, FarmLayout, LayoutSpec
from wwcore.scenario.faults import FaultKind, FaultSpec
from wwcore.scenario.turbine import NoiseConvention, check_turbine_fault, sensor_sigma
from wwcore.scenario.wind import check_direction_points, direction_at, unwrap_direction_points
from wwcore.site import SiteInfo
from wwcore.turbine_params import BENCHMARK

N_TURBINES = 9  # turbines of the paper's farm (seed 001's 3 × 3); any other farm's come from its layout
GRID = 3  # turbines per side of the square grid
ROTOR_DIAMETER_M = 115.0  # m, 2R of the benchmark turbine (PARAMETERS.md a.1)
FARM_DT_S = 0.1  # s, sample time of the farm controller, farm FDI and met mast [PAPER] Section 2 (10 Hz)
TURBINE_RATED_MW = 4.8  # MW, rated power of one farm turbine (PARAMETERS.md a.1)
ROW_TOLERANCE_D = 0.5  # D, turbines of a layout within this distance along the wind form one row
VEER_BOUND_SIGMA = 4.0  # the random veer is held within ± this many σ (the wake tables cover the bound)
WakeModel = Literal["rows", "gauss", "jensen"]

FARM_FAULT_NAMES: dict[FaultKind, str] = {
    FaultKind.DEBRIS: "debris",
    FaultKind.OFFSET: "pitch_misalignment",
    FaultKind.PITCH_OFFSET: "pitch_misalignment",
    FaultKind.DRIVETRAIN_WEAR: "drivetrain",
}
"""Kind of a farm fault → the name the farm detectors flag and the scorecard uses (``wt<k>:<name>``)."""
FARM_FAULT_TYPES: tuple[str, ...] = ("debris", "pitch_misalignment", "drivetrain")
"""The paper's faults 1, 2 and 3, in that order."""


class FarmDemand(BaseModel):
    """The farm power demand P_ref,farm the grid operator sends, in one of two modes.

    ``profile``: piecewise linear through ``points`` [(t in s, MW)], held after the last point (a constant is one
    point; a step is two points 0.1 s apart). ``available_fraction``: a delta-control set point,
    ``fraction`` × the farm's available power estimated from the met-mast wind averaged over ``averaging_s``
    (first-order filter) with the static wake model, held for ``update_s`` between updates.
    """

    model_config = ConfigDict(extra="forbid")

    mode: Literal["profile", "available_fraction"] = "available_fraction"
    fraction: float | None = Field(default=0.8, gt=0.0, le=1.0, description="–, share of the available power")
    averaging_s: float = Field(default=60.0, gt=0.0, le=3600.0, description="s, time constant of the mast average")
    update_s: float = Field(default=30.0, ge=0.1, le=3600.0, description="s, the set point is held this long")
    points: list[tuple[float, float]] | None = Field(
        default=None, description="[(t in s, demand in MW)] for mode 'profile'"
    )

    @model_validator(mode="after")
    def _mode_fields(self) -> FarmDemand:
        if self.mode == "profile":
            if not self.points:
                raise ValueError("points: a 'profile' demand needs at least one (t_s, MW) point")
            times = [t for t, _ in self.points]
            if any(b <= a for a, b in itertools.pairwise(times)) or times[0] < 0.0:
                raise ValueError("points: times must be ≥ 0 and increase strictly")
            for _, mw in self.points:
                if not mw >= 0.0:
                    raise ValueError(f"points: demand {mw} MW is below 0 MW")
        elif self.points is not None:
            raise ValueError("points: only a 'profile' demand takes points")
        return self


class FarmPlant(BaseModel):
    """Benchmark turbines (PARAMETERS.md a): the 3 × 3 grid of PARAMETERS.md b, or a ``layout`` (FLORIS wakes)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["farm"] = "farm"
    wind_case: Literal[1, 2] = Field(default=1, description="1: wind along the grid lines; 2: along the diagonal")
    spacing_m: float = Field(default=805.0, ge=230.0, le=3000.0, description="m, grid spacing (7 D) [PROPOSED]")
    mast_distance_m: float = Field(
        default=287.5, ge=0.0, le=3000.0, description="m, met mast upwind of the front row (5 D) [PROPOSED]"
    )
    mast_noise_mps: float = Field(default=0.5, ge=0.0, le=5.0, description="m/s, σ of the mast reading [PROPOSED]")
    mast_direction_noise_deg: float = Field(
        default=5.0,
        ge=0.0,
        le=45.0,
        description="deg, σ of the mast's wind-vane reading (white, 10 Hz; vane accuracy and the turbulence's "
        "direction swings at the mast) [PROPOSED]",
    )
    coherent_ti: float = Field(
        default=0.05, ge=0.0, le=0.3, description="–, σ/mean of the slow turbulence all turbines share [PROPOSED]"
    )
    coherent_time_s: float = Field(
        default=60.0, gt=0.0, le=3600.0, description="s, correlation time of the shared turbulence [PROPOSED]"
    )
    row_coherence: float = Field(
        default=0.0,
        ge=0.0,
        le=1.0,
        description="–, share of each turbine's turbulence variance common to its row: 0 independent turbines (7 D "
        "apart, the physical choice), 1 identical rows (what the paper's row comparisons presume) [PROPOSED]",
    )
    wakes: bool = Field(default=True, description="wake deficits on downstream turbines (false: free stream)")
    wake_model: WakeModel = Field(
        default="gauss",
        description="'gauss' / 'jensen': FLORIS's Gauss / Jensen wakes between every pair of turbines, tabulated at "
        "start (docs/farm.md, Wakes and layouts); 'rows': the paper's row model (Jensen between rows, 3 × 3 only)",
    )
    wake_expansion: float = Field(
        default=0.05, ge=0.0, le=0.2, description="–, Jensen wake decay k of the row model [PROPOSED]"
    )
    wake_added_turbulence: bool = Field(
        default=True,
        description="FLORIS wakes: each turbine's own turbulence scaled to the turbulence intensity FLORIS gives it "
        "(ambient plus wake-added); false: the ambient's for every turbine",
    )
    layout: LayoutSpec | None = Field(
        default=None,
        description="turbine positions: a grid, coordinates or a shipped layout file (wwcore.layout); None: the "
        "paper's 3 × 3 at spacing_m. Needs a FLORIS wake model and wind_direction_deg",
    )
    wind_direction_deg: float | None = Field(
        default=None,
        ge=0.0,
        lt=360.0,
        description="deg clockwise from north, where the wind comes from; None: the wind case's on the 3 × 3 "
        "(1: 270, 2: 315)",
    )
    wind_direction_profile: list[tuple[float, float]] | None = Field(
        default=None,
        description="[(t in s, deg clockwise from north)]: the wind direction piecewise linear through these points, "
        "each joined to the previous along the shorter arc (350 then 10 is a veer of +20 deg), held before the first "
        "and after the last; None: the constant wind_direction_deg (or the wind case's). FLORIS wakes only",
    )
    veer_sigma_deg: float = Field(
        default=0.0,
        ge=0.0,
        le=20.0,
        description="deg, stationary σ of the slow random veer about the direction (first-order Gauss–Markov, "
        "bounded at ±4 σ; plant_sim.farm.direction); 0: none. FLORIS wakes only [PROPOSED]",
    )
    veer_time_s: float = Field(
        default=600.0, ge=10.0, le=7200.0, description="s, correlation time of the random veer [PROPOSED]"
    )
    noise_convention: NoiseConvention = Field(
        default="sigma", description="read the benchmark's sensor noise numbers as σ (papers) or as variances"
    )
    cancel_3p_in_hold: bool = Field(
        default=True,
        description="a turbine asked to hold also cancels the drive-train fault's 3P shaft torque with its converter "
        "(docs/farm.md D-C4) [PROPOSED]",
    )
    demand: FarmDemand = Field(default_factory=FarmDemand)

    @field_validator("wind_direction_profile")
    @classmethod
    def _check_direction_profile(cls, points: list[tuple[float, float]] | None) -> list[tuple[float, float]] | None:
        if points is not None:
            check_direction_points(points)
        return points

    @model_validator(mode="after")
    def _geometry(self) -> FarmPlant:
        moving = self.wind_direction_profile is not None or self.veer_sigma_deg > 0.0
        if self.wake_model == "rows" and moving:
            field = "wind_direction_profile" if self.wind_direction_profile is not None else "veer_sigma_deg"
            raise ValueError(
                f"{field}: the row model (wake_model 'rows') knows the paper's two fixed wind cases only; a moving "
                "wind direction needs wake_model 'gauss' or 'jensen'"
            )
        if self.wind_direction_profile is not None and self.wind_direction_deg is not None:
            raise ValueError("wind_direction_profile: give the constant wind_direction_deg or a profile, not both")
        if self.veer_sigma_deg > 0.0 and self.wind_direction_deg is None and self.wind_direction_profile is None:
            raise ValueError(
                "veer_sigma_deg: the random veer moves about a direction of the scenario's own: give "
                "wind_direction_deg or wind_direction_profile (the wind cases are the paper's fixed directions)"
            )
        if self.wake_model == "rows" and self.layout is not None:
            raise ValueError(
                "layout: the row model (wake_model 'rows') is the paper's, for its 3 × 3 grid; "
                "a layout needs wake_model 'gauss' or 'jensen'"
            )
        # Checks on values, not on which keys were given: a dumped and re-read plant (live adapter) must pass.
        if self.wake_model == "rows" and not self.wake_added_turbulence:
            raise ValueError(
                "wake_added_turbulence: the row model (wake_model 'rows') has no wake-added turbulence; "
                "choose wake_model 'gauss' or 'jensen'"
            )
        if self.wake_model == "rows" and self.wind_direction_deg is not None:
            raise ValueError(
                "wind_direction_deg: the row model (wake_model 'rows') knows the paper's two wind cases only; "
                "set wind_case, or choose wake_model 'gauss' or 'jensen'"
            )
        if self.layout is not None and self.wind_direction_deg is None and self.wind_direction_profile is None:
            raise ValueError(
                "wind_direction_deg: a farm with a layout needs the wind direction (deg from north, or a "
                "wind_direction_profile)"
            )
        if self.layout is not None and self.spacing_m != type(self).model_fields["spacing_m"].default:
            raise ValueError("spacing_m: the layout gives the positions; spacing_m is the paper's 3 × 3 spacing")
        n = self.n_turbines  # resolves the layout (overlapping turbines, empty layouts are refused there)
        if self.wind_case != type(self).model_fields["wind_case"].default and not self.is_paper_farm():
            raise ValueError(
                f"wind_case: the wind cases are directions on seed 001's 3 × 3 (1: 270°, 2: 315°); this farm has "
                f"{n} turbines with wind from {self.direction_deg:g}°: leave wind_case out and give wind_direction_deg"
            )
        if self.demand.points is not None:
            top = n * TURBINE_RATED_MW
            for _, mw in self.demand.points:
                if mw > top * (1.0 + 1e-12):
                    raise ValueError(f"demand.points: demand {mw} MW is above the farm's {top:g} MW ({n} turbines)")
        return self

    @property
    def n_turbines(self) -> int:
        return self.resolved_layout().n_turbines

    def site(self, dt: float = BENCHMARK.dt) -> SiteInfo:
        """What the farm's supervisor may know: the turbines' parameters and sensor noise, their positions (the
        resolved layout, east/north in m) and the mast's distance; never the wind case or direction (a detector
        estimates it, ``service.farm.interfaces.FarmContext.rows`` groups the layout for any direction)."""
        layout = self.resolved_layout()
        n = layout.n_turbines
        spacing = self.spacing_m if self.layout is None else (layout.spacing_d() * ROTOR_DIAMETER_M if n > 1 else None)
        return SiteInfo(
            kind="farm",
            turbines=tuple(range(1, n + 1)),
            dt=float(dt),
            rated_power_w=BENCHMARK.rated_power,
            noise_convention=self.noise_convention,
            sensor_sigma=sensor_sigma(self.noise_convention),
            positions_m=tuple((float(x) + 0.0, float(y) + 0.0) for x, y in zip(layout.x, layout.y, strict=True)),
            spacing_m=spacing,
            mast_distance_m=self.mast_distance_m,
            rotor_diameter_m=ROTOR_DIAMETER_M,
        )

    # -- geometry ---------------------------------------------------------------------------------------------
    @property
    def direction_deg(self) -> float:
        """Where the wind comes from at t = 0 (before any random veer), deg clockwise from north, 0 … <360 (wind
        case 1: 270, case 2: 315 on the 3 × 3); the geometry below (rows, distances) is for this direction."""
        if self.wind_direction_profile is not None:
            return float(direction_at(self.wind_direction_profile, 0.0)) % 360.0
        return SEED001_DIRECTIONS_DEG[self.wind_case] if self.wind_direction_deg is None else self.wind_direction_deg

    @property
    def direction_varies(self) -> bool:
        """Whether the wind direction moves during a run (a profile through distinct directions, or random veer)."""
        if self.veer_sigma_deg > 0.0:
            return True
        points = self.wind_direction_profile
        return points is not None and bool(np.ptp(unwrap_direction_points(points)[1]) > 0.0)

    def direction_profile_deg(self, t: np.ndarray | float) -> np.ndarray:
        """The direction profile (deg, unwrapped: continuous, may leave 0 … 360) at times ``t``, without the veer."""
        if self.wind_direction_profile is None:
            return np.full(np.shape(t), self.direction_deg)
        return direction_at(self.wind_direction_profile, t)

    def direction_sector_deg(self) -> tuple[float, float]:
        """(lowest, highest) direction a run can reach, deg, unwrapped: the profile's range ± the veer's bound."""
        if self.wind_direction_profile is None:
            lo = hi = self.direction_deg
        else:
            degrees = unwrap_direction_points(self.wind_direction_profile)[1]
            lo, hi = float(degrees.min()), float(degrees.max())
        bound = VEER_BOUND_SIGMA * self.veer_sigma_deg
        return lo - bound, hi + bound

    def resolved_layout(self) -> FarmLayout:
        """The turbine positions in metres (east, north) for the benchmark rotor."""
        if self.layout is None:
            xy = np.array([self.position(t) for t in range(1, N_TURBINES + 1)])
            return FarmLayout(xy[:, 0], -xy[:, 1], ROTOR_DIAMETER_M, source="3x3 grid")
        return self.layout.resolve(ROTOR_DIAMETER_M)

    def _own_geometry(self) -> bool:
        """Whether the farm is placed by a layout or a direction of its own (not the paper's wind-case geometry)."""
        return self.layout is not None or self.wind_direction_deg is not None or self.wind_direction_profile is not None

    def is_paper_farm(self) -> bool:
        """Whether this is seed 001's farm (3 × 3 at spacing_m, wind along a wind case) that the supervisor knows."""
        if self.direction_varies:
            return False
        if self.layout is None and self.wind_direction_deg is None and self.wind_direction_profile is None:
            return True
        mine = self.resolved_layout()
        paper = FarmPlant(spacing_m=self.spacing_m).resolved_layout()
        same_place = (
            mine.n_turbines == N_TURBINES
            and np.allclose(mine.x, paper.x, atol=1e-3)
            and np.allclose(mine.y, paper.y, atol=1e-3)
        )
        return same_place and math.isclose(self.direction_deg, SEED001_DIRECTIONS_DEG[self.wind_case], abs_tol=1e-9)

    def position(self, turbine: int) -> tuple[float, float]:
        """(x, y) in m of a turbine (1-based) on the paper's 3 × 3: x along the grid columns, y along the grid rows."""
        col, row = (turbine - 1) % GRID, (turbine - 1) // GRID
        return col * self.spacing_m, row * self.spacing_m

    def along_wind_m(self, turbine: int) -> float:
        """Distance in m of a turbine from the front row, along the wind (case 1: x; case 2: (x + y)/√2)."""
        if self._own_geometry():
            return float(self.downwind_m()[turbine - 1])
        x, y = self.position(turbine)
        return x if self.wind_case == 1 else (x + y) / math.sqrt(2.0)

    def downwind_m(self) -> np.ndarray:
        """Distance in m of every turbine from the most upwind one, along the wind (``FarmLayout.wind_frame``)."""
        return self.resolved_layout().wind_frame(self.direction_deg).downwind

    def rows(self) -> list[tuple[int, ...]]:
        """Turbine numbers grouped by distance along the wind, front to back (the paper's rows on its 3 × 3; for a
        layout or another direction, within ``ROW_TOLERANCE_D`` rotor diameters)."""
        if self._own_geometry():
            groups = self.resolved_layout().groups_along_wind(self.direction_deg, ROW_TOLERANCE_D * ROTOR_DIAMETER_M)
            return [tuple(i + 1 for i in g) for g in groups]
        by_distance: dict[float, list[int]] = {}
        for t in range(1, N_TURBINES + 1):
            by_distance.setdefault(round(self.along_wind_m(t), 6), []).append(t)
        return [tuple(by_distance[d]) for d in sorted(by_distance)]

    def row_of(self) -> list[int]:
        """Row index (0 = front) of turbines 1 … N."""
        out = [0] * self.n_turbines
        for i, members in enumerate(self.rows()):
            for t in members:
                out[t - 1] = i
        return out

    def row_distances_m(self) -> list[float]:
        """Distance in m of each row from the front row, along the wind."""
        if self._own_geometry():
            s = self.downwind_m()
            return [float(s[members[0] - 1]) for members in self.rows()]
        return [self.along_wind_m(members[0]) for members in self.rows()]


def check_farm_fault(fault: FaultSpec, n_turbines: int) -> list[tuple[str, str]]:
    """Problems with one fault on a farm turbine, as (field, message) pairs; empty when it is valid.

    The farm's own faults (debris on the rotor, a pitch command offset, drive-train wear) are checked here; every
    other fault is a fault of the single turbine and follows ``check_turbine_fault``.
    """
    pitch = {f"pitch_actuator_{i}" for i in (1, 2, 3)}
    farm_kind = {FaultKind.DEBRIS: {"rotor"}, FaultKind.DRIVETRAIN_WEAR: {"drivetrain"}}
    if fault.target == "rotor" and fault.kind is not FaultKind.DEBRIS:
        return [("kind", f"{fault.kind.value!r} cannot act on the rotor; use 'debris'")]
    if fault.kind in farm_kind and fault.target not in farm_kind[fault.kind]:
        return [("target", f"a {fault.kind.value} fault acts on {sorted(farm_kind[fault.kind])[0]!r}")]
    if fault.kind not in farm_kind and not (fault.kind is FaultKind.OFFSET and fault.target in pitch):
        return check_turbine_fault(fault, n_turbines)
    problems: list[tuple[str, str]] = []
    if fault.turbine > n_turbines:
        problems.append(("turbine", f"turbine {fault.turbine} does not exist (the farm has {n_turbines})"))
    if fault.value is None:
        problems.append(("value", f"a {fault.kind.value} fault needs a value"))
        return problems
    match fault.kind:
        case FaultKind.DEBRIS:
            if not 0.5 <= fault.value < 1.0:
                problems.append(("value", f"{fault.value} is outside the range 0.5 … <1 (power output factor)"))
        case FaultKind.OFFSET:
            if not -5.0 <= fault.value <= 5.0 or fault.value == 0.0:
                problems.append(("value", f"{fault.value} is outside the range −5 … 5 deg (nonzero)"))
        case FaultKind.DRIVETRAIN_WEAR:
            if not 0.0 < fault.value <= 20.0:
                problems.append(("value", f"{fault.value} is outside the range 0 … 20 mrad (transmission error)"))
    return problems


def farm_fault_name(fault: FaultSpec) -> str:
    """What a detector flags for this fault: a farm fault type, or the target of a turbine fault."""
    if fault.kind in FARM_FAULT_NAMES and (fault.kind is not FaultKind.OFFSET or fault.target.startswith("pitch_")):
        return FARM_FAULT_NAMES[fault.kind]
    return fault.target
