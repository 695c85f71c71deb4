r"""Wind-farm layouts and their geometry in the wind: where the turbines stand, and how they line up for a direction.

A scenario gives a layout in one of three forms (``LayoutSpec``, a pydantic union on ``kind``):

* ``grid``: ``rows`` × ``columns`` turbines, ``column_spacing_d`` rotor diameters apart along a row and
  ``row_spacing_d`` between rows. ``orientation_deg`` is the bearing (degrees clockwise from north) along which a
  row runs, from its first turbine to its second; the next row stands to the right of it (orientation 90°: rows run
  west → east and follow each other southwards). Turbines are numbered row by row from the first corner.
* ``coordinates``: explicit ``x_m`` (east) and ``y_m`` (north) in metres (checked against the benchmark rotor when
  the scenario is read, and against the rotor it is resolved for).
* ``file``: the ``name`` of a layout file the project ships (``available_layouts()``), scaled to the turbine's rotor
  by spacing in diameters: a file records the rotor diameter D_f it was built for, and every coordinate is multiplied
  by D/D_f, so Horns Rev 1's 7 D with the V80's D_f = 80 m becomes 7 D of the 115 m benchmark rotor (805 m).

``resolve(D)`` turns any of them into a ``FarmLayout`` (metres, east/north, origin at the first turbine), which
refuses an empty layout, more than ``MAX_TURBINES`` turbines, non-finite coordinates, and turbines closer than
``MIN_SPACING_D`` = 1.5 D to each other, with a message that names the offending turbines. Indices are 0-based in
every array; turbine *numbers* (index + 1) appear only in messages.

**Wind frame.** The wind direction θ is meteorological: degrees clockwise from north of where the wind comes
*from* (270°: a westerly, blowing towards +x). The flow's unit vector is f = (−sin θ, −cos θ) and its left normal
n = (cos θ, −sin θ), so for a turbine at (x, y):

.. math::  s = x f_x + y f_y \ (\text{downwind}),\qquad c = x n_x + y n_y \ (\text{crosswind, positive to the left
           looking downwind})

which at θ = 270° is (s, c) = (x, y), FLORIS's rotated frame. ``wind_frame`` returns s measured from the most
upwind turbine (so the front row has s = 0) and c from the layout's centroid; ``along_wind_matrix`` returns
x_ij = s_j − s_i (positive when j is downwind of i), the distance a wake travels from i to j, from which the
plant takes its travel delays x_ij / v̄. ``groups_along_wind`` forms what the paper's rows become for any layout
and direction: turbines at the same downwind distance within a tolerance.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from importlib import resources
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from wwcore.turbine_params import BENCHMARK

MAX_TURBINES = 250  # turbines in one layout (the issue asks for at least 150)
MIN_SPACING_D = 1.5  # rotor diameters: two turbines closer than this overlap (rotor and tower clearance)
MAX_EXTENT_M = 100_000.0  # m, largest distance of a turbine from the first one (a typo in a coordinate, not a farm)
LAYOUT_PACKAGE = "wwcore.data.layouts"
DIAMETER_KEY = "rotor_diameter_m:"
BENCHMARK_DIAMETER = 2.0 * BENCHMARK.radius  # m, the rotor a scenario's explicit coordinates are checked against


# ---- the resolved layout ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class WindFrame:
    """Turbine coordinates in the wind (m): ``downwind`` from the most upwind turbine, ``crosswind`` from the centroid
    (positive to the left looking downwind)."""

    direction_deg: float
    downwind: np.ndarray
    crosswind: np.ndarray


@dataclass(frozen=True)
class FarmLayout:
    """Turbine positions in metres (``x`` east, ``y`` north) for a rotor of ``rotor_diameter`` m; validated."""

    x: np.ndarray
    y: np.ndarray
    rotor_diameter: float
    source: str = "coordinates"
    _key: bytes = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        x = np.array(self.x, dtype=float).reshape(-1)
        y = np.array(self.y, dtype=float).reshape(-1)
        check_positions(x, y, self.rotor_diameter)
        x.flags.writeable = False
        y.flags.writeable = False
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "_key", np.concatenate([x, y, [self.rotor_diameter]]).tobytes())

    @property
    def n_turbines(self) -> int:
        return len(self.x)

    def fingerprint(self) -> bytes:
        """Bytes that identify the geometry (positions and D), for cache keys."""
        return self._key

    def spacing_d(self) -> float:
        """Smallest distance between two turbines, in rotor diameters (inf for a single turbine)."""
        return nearest_distance(self.x, self.y)[0] / self.rotor_diameter

    def wind_frame(self, direction_deg: float) -> WindFrame:
        """(downwind, crosswind) of every turbine for wind from ``direction_deg`` (see the module docstring)."""
        th = math.radians(direction_deg)
        s = -self.x * math.sin(th) - self.y * math.cos(th)
        c = self.x * math.cos(th) - self.y * math.sin(th)
        return WindFrame(float(direction_deg), s - s.min(), c - c.mean())

    def along_wind_matrix(self, direction_deg: float) -> np.ndarray:
        """x_ij = s_j − s_i (m), shape (N, N): how far j stands downwind of i (negative: upwind)."""
        s = self.wind_frame(direction_deg).downwind
        return s[None, :] - s[:, None]

    def groups_along_wind(self, direction_deg: float, tolerance_m: float) -> list[tuple[int, ...]]:
        """Turbine indices grouped by downwind distance, front to back, each group sorted by index.

        A group starts at the most upwind turbine not yet grouped and takes every turbine at most ``tolerance_m``
        further downwind (anchored at the group's first turbine, so a slowly drifting line is cut into groups no
        wider than the tolerance rather than chained into one).
        """
        if not tolerance_m >= 0.0:
            raise ValueError(f"tolerance_m must be ≥ 0, got {tolerance_m}")
        s = self.wind_frame(direction_deg).downwind
        order = np.argsort(s, kind="stable")
        groups: list[tuple[int, ...]] = []
        k = 0
        while k < len(order):
            anchor = s[order[k]]
            end = k
            while end < len(order) and s[order[end]] - anchor <= tolerance_m:
                end += 1
            groups.append(tuple(sorted(int(i) for i in order[k:end])))
            k = end
        return groups


def nearest_distance(x: np.ndarray, y: np.ndarray) -> tuple[float, int, int]:
    """(distance in m, i, j) of the closest pair of positions; (inf, −1, −1) for fewer than two."""
    if len(x) < 2:
        return math.inf, -1, -1
    d = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    d[np.diag_indices_from(d)] = np.inf
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return float(d[i, j]), int(min(i, j)), int(max(i, j))


def check_positions(x: np.ndarray, y: np.ndarray, rotor_diameter: float) -> None:
    """Raise ValueError, naming the turbines, for an empty, oversized, non-finite or overlapping layout."""
    if not (math.isfinite(rotor_diameter) and rotor_diameter > 0.0):
        raise ValueError(f"rotor diameter must be a positive number of metres, got {rotor_diameter}")
    if x.shape != y.shape:
        raise ValueError(f"x has {x.size} coordinates and y {y.size}: give one (x, y) per turbine")
    n = x.size
    if n == 0:
        raise ValueError("the layout is empty: a farm needs at least one turbine")
    if n > MAX_TURBINES:
        raise ValueError(f"the layout has {n} turbines; at most {MAX_TURBINES} are supported")
    bad = np.flatnonzero(~(np.isfinite(x) & np.isfinite(y)))
    if bad.size:
        raise ValueError(f"turbine {bad[0] + 1} has a non-finite coordinate ({x[bad[0]]}, {y[bad[0]]})")
    far = np.hypot(x - x[0], y - y[0])
    if far.max() > MAX_EXTENT_M:
        k = int(np.argmax(far))
        raise ValueError(
            f"turbine {k + 1} is {far[k] / 1000:.1f} km from turbine 1; a layout spans at most "
            f"{MAX_EXTENT_M / 1000:.0f} km (a coordinate in the wrong unit?)"
        )
    d, i, j = nearest_distance(x, y)
    minimum = MIN_SPACING_D * rotor_diameter
    if d < minimum:
        raise ValueError(
            f"turbines {i + 1} and {j + 1} overlap: {d:.1f} m apart ({d / rotor_diameter:.2f} D); "
            f"the minimum is {MIN_SPACING_D} D = {minimum:.1f} m"
        )


# ---- layout files the project ships -------------------------------------------------------------------------------
def available_layouts() -> list[str]:
    """Names of the shipped layout files (``wwcore/data/layouts/<name>.csv``)."""
    root = resources.files(LAYOUT_PACKAGE)
    return sorted(p.name[:-4] for p in root.iterdir() if p.name.endswith(".csv"))


@functools.lru_cache(maxsize=16)
def read_layout_file(name: str) -> tuple[np.ndarray, np.ndarray, float, str]:
    """(x, y, D_f, description) of a shipped layout, coordinates in m as in the file, D_f its rotor diameter."""
    if name not in available_layouts():
        raise ValueError(f"no layout file {name!r}; the project ships {available_layouts()}")
    text = resources.files(LAYOUT_PACKAGE).joinpath(f"{name}.csv").read_text(encoding="utf-8")
    comments = [line[1:].strip() for line in text.splitlines() if line.startswith("#")]
    diameters = [float(c[len(DIAMETER_KEY) :]) for c in comments if c.startswith(DIAMETER_KEY)]
    if len(diameters) != 1:
        raise ValueError(f"layout file {name!r} must state its rotor diameter once ('# {DIAMETER_KEY} <m>')")
    rows = [line.split(",") for line in text.splitlines() if line and not line.startswith("#")]
    header, body = rows[0], rows[1:]
    if header != ["turbine", "x_m", "y_m"]:
        raise ValueError(f"layout file {name!r}: header must be turbine,x_m,y_m, got {','.join(header)}")
    numbers = [int(r[0]) for r in body]
    if numbers != list(range(1, len(body) + 1)):
        raise ValueError(f"layout file {name!r}: turbines must be numbered 1 … {len(body)} in order")
    xy = np.array([[float(r[1]), float(r[2])] for r in body])
    return xy[:, 0], xy[:, 1], diameters[0], comments[0] if comments else name


# ---- scenario forms -----------------------------------------------------------------------------------------------
class GridLayout(BaseModel):
    """``rows`` × ``columns`` turbines, spacings in rotor diameters, rows along the bearing ``orientation_deg``."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["grid"] = "grid"
    rows: int = Field(ge=1, le=MAX_TURBINES, description="number of rows")
    columns: int = Field(ge=1, le=MAX_TURBINES, description="turbines per row")
    column_spacing_d: float = Field(default=7.0, ge=MIN_SPACING_D, le=50.0, description="D, along a row")
    row_spacing_d: float = Field(default=7.0, ge=MIN_SPACING_D, le=50.0, description="D, between rows")
    orientation_deg: float = Field(
        default=90.0, ge=-360.0, le=360.0, description="deg from north, bearing along which a row runs"
    )

    @model_validator(mode="after")
    def _size(self) -> GridLayout:
        if self.rows * self.columns > MAX_TURBINES:
            raise ValueError(f"{self.rows} × {self.columns} turbines; at most {MAX_TURBINES} are supported")
        return self

    def resolve(self, rotor_diameter: float) -> FarmLayout:
        k = np.arange(self.rows * self.columns)
        along = (k % self.columns) * self.column_spacing_d * rotor_diameter
        back = (k // self.columns) * self.row_spacing_d * rotor_diameter
        th = math.radians(self.orientation_deg)
        # along a row: bearing θ → (sin θ, cos θ); the next row to its right: bearing θ + 90° → (cos θ, −sin θ)
        x = along * math.sin(th) + back * math.cos(th)
        y = along * math.cos(th) - back * math.sin(th)
        return FarmLayout(x, y, rotor_diameter, source=f"grid {self.rows}x{self.columns}")


class CoordinateLayout(BaseModel):
    """Explicit positions: ``x_m`` east and ``y_m`` north, metres, one pair per turbine."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["coordinates"] = "coordinates"
    x_m: list[float] = Field(max_length=MAX_TURBINES)
    y_m: list[float] = Field(max_length=MAX_TURBINES)

    def resolve(self, rotor_diameter: float) -> FarmLayout:
        return FarmLayout(np.array(self.x_m), np.array(self.y_m), rotor_diameter, source="coordinates")

    @model_validator(mode="after")
    def _positions(self) -> CoordinateLayout:
        check_positions(np.array(self.x_m, dtype=float), np.array(self.y_m, dtype=float), BENCHMARK_DIAMETER)
        return self


class FileLayout(BaseModel):
    """A shipped layout file by ``name``, scaled by rotor diameters (``scale_to_rotor``) or taken in metres."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["file"] = "file"
    name: str = Field(max_length=64)
    scale_to_rotor: bool = Field(default=True, description="multiply the coordinates by D / D_file")

    @model_validator(mode="after")
    def _known(self) -> FileLayout:
        if self.name not in available_layouts():
            raise ValueError(f"no layout file {self.name!r}; the project ships {available_layouts()}")
        return self

    def resolve(self, rotor_diameter: float) -> FarmLayout:
        x, y, d_file, _ = read_layout_file(self.name)
        scale = rotor_diameter / d_file if self.scale_to_rotor else 1.0
        return FarmLayout((x - x[0]) * scale, (y - y[0]) * scale, rotor_diameter, source=f"file {self.name}")


LayoutSpec = Annotated[GridLayout | CoordinateLayout | FileLayout, Field(discriminator="kind")]
"""A layout as a scenario gives it (``kind`` = grid | coordinates | file)."""

SEED001_LAYOUT = FileLayout(name="seed001_3x3")
"""The paper's 3 × 3 (wind case 1: 270°, case 2: 315°)."""
SEED001_DIRECTIONS_DEG = {1: 270.0, 2: 315.0}
"""The paper's two wind cases as meteorological directions on ``SEED001_LAYOUT``."""
HORNS_REV_1 = FileLayout(name="hornsrev1")
