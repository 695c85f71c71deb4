"""The farm map of the live dashboard: every turbine at its position, coloured by its state, and the wind.

The plant logs what does not change during a run, once and static: the turbines' positions (east, north in m, drawn
with north up), their labels ``T1 … Tn``, a disc of the rotor's radius each, and, where the scenario's direction is
fixed, an arrow along the wind from the upwind edge of the farm. Where the direction moves (a profile or veer), the
plant draws the arrow on the run's timeline from the met mast's vane (``WindArrow``: its readings' circular mean
over ``VANE_AVERAGING_S``, drawn again when it has turned by ``REDRAW_DEG``). The supervisor logs only the
colours, on the run's timeline and only when a turbine's state changes, so the map costs nothing while the farm is
healthy. Rerun merges the two processes' components of the entity ``/farm/map/turbines`` into one picture.

States, from a turbine's row of the farm supervisor's references (``wwcore.wire.FARM_REFS``):

- **derated**: accommodation mode 2 or 3 (eq. (26): power reference lowered, with or without the held torque);
- **flagged**: a fault flag up and no derating;
- **accommodated**: no flag, but an accommodation still acting (modes 1, 4, 5: debris law, pitch trim, 3P
  cancellation);
- **healthy**: no flag, mode 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

MAP = "/farm/map"
TURBINES = f"{MAP}/turbines"
WIND = f"{MAP}/wind"

STATES = ("healthy", "flagged", "derated", "accommodated")
COLOUR_NAMES = ("green", "red", "orange", "blue")  # of STATE_COLOURS, for the view's title
STATE_COLOURS = np.array(
    [(40, 170, 80, 255), (220, 50, 50, 255), (240, 140, 30, 255), (70, 110, 220, 255)], dtype=np.uint8
)  # by index of STATES: green, red, orange, blue
DERATED_MODES = (2, 3)
WIND_COLOUR = (20, 20, 20, 255)
VANE_AVERAGING_S = 60.0  # s, time constant of the vane's running circular mean (the paper detector's default)
REDRAW_DEG = 2.0  # deg, the arrow is drawn again when the mean has turned this far


@dataclass(frozen=True)
class FarmGeometry:
    """What the map draws of the site: positions in m (east, north), the rotor diameter in m and where the wind
    comes from, in degrees clockwise from north (meteorological convention: 270 is a wind from the west)."""

    east_m: np.ndarray
    north_m: np.ndarray
    rotor_diameter_m: float
    wind_from_deg: float
    wind_moves: bool = False  # a direction profile or veer: the arrow follows the vane (``WindArrow``)

    def __post_init__(self) -> None:
        if len(self.east_m) != len(self.north_m) or len(self.east_m) == 0:
            raise ValueError("farm map: east_m and north_m need one entry per turbine, at least one")


def geometry_of(plant: Any) -> FarmGeometry:
    """The map of a farm scenario's plant section (``wwcore.scenario.farm.FarmPlant``): its resolved layout and
    the wind direction."""
    layout = plant.resolved_layout()
    moves = bool(getattr(plant, "direction_varies", False))
    return FarmGeometry(layout.x, layout.y, layout.rotor_diameter, plant.direction_deg, moves)


def screen_xy(east_m: np.ndarray, north_m: np.ndarray) -> np.ndarray:
    """(n, 2) points of a 2-D view, whose y axis points down the screen: north is drawn up."""
    return np.column_stack([np.asarray(east_m, dtype=float), -np.asarray(north_m, dtype=float)])


def wind_arrow(geometry: FarmGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Origin and vector (screen coordinates) of an arrow that blows across the farm: it starts one rotor diameter
    upwind of the farm's most upwind turbine and is as long as the farm is deep along the wind (at least 3 D)."""
    toward = math.radians(geometry.wind_from_deg + 180.0)  # the direction the air moves, clockwise from north
    along = np.array([math.sin(toward), math.cos(toward)])  # (east, north) unit vector
    en = np.column_stack([geometry.east_m, geometry.north_m])
    depth = en @ along
    centre = en.mean(axis=0)
    start = centre + along * (depth.min() - centre @ along - geometry.rotor_diameter_m)
    length = max(float(depth.max() - depth.min()), 3.0 * geometry.rotor_diameter_m)
    origin = screen_xy(start[:1], start[1:])[0]
    vector = np.array([along[0], -along[1]]) * length
    return origin, vector


def log_geometry(rec: rr.RecordingStream, geometry: FarmGeometry) -> None:
    """The map's static part (the plant process): positions, labels, rotor discs, and the wind arrow."""
    n = len(geometry.east_m)
    rec.log(
        TURBINES,
        rr.Points2D(
            screen_xy(geometry.east_m, geometry.north_m),
            radii=geometry.rotor_diameter_m / 2.0,
            labels=[f"T{t}" for t in range(1, n + 1)],
            show_labels=True,
        ),
        static=True,  # no colours here: a static component would hide the supervisor's colours on the timeline
    )
    if not geometry.wind_moves:
        rec.log(WIND, _arrow(geometry), static=True)


def _arrow(geometry: FarmGeometry) -> rr.Arrows2D:
    origin, vector = wind_arrow(geometry)
    return rr.Arrows2D(
        origins=[origin],
        vectors=[vector],
        colors=[WIND_COLOUR],
        radii=geometry.rotor_diameter_m / 8.0,
        labels=[f"wind from {geometry.wind_from_deg % 360:.0f}°"],
        show_labels=True,
    )


class WindArrow:
    """The plant's side where the direction moves: the vane's running circular mean, m_k = m_{k−1} + (Δt/T)
    (u_k − m_{k−1}) on unit vectors u_k = (sin θ_k, cos θ_k) with T = ``VANE_AVERAGING_S``, and the arrow drawn at
    its angle on the timeline when that has turned by ``REDRAW_DEG`` since the last drawing (and at the first
    reading)."""

    def __init__(self, geometry: FarmGeometry):
        self.geometry = geometry
        self.mean: np.ndarray | None = None
        self.t: float | None = None
        self.drawn_deg: float | None = None
        self.draws = 0

    def update(self, rec: rr.RecordingStream, timeline: str, t: float, vane_deg: float) -> bool:
        """Take one vane reading (deg from north) at simulation time ``t`` (s); True if the arrow was drawn."""
        if not math.isfinite(vane_deg):
            return False
        unit = np.array([math.sin(math.radians(vane_deg)), math.cos(math.radians(vane_deg))])
        if self.mean is None or self.t is None:
            self.mean = unit
        else:
            weight = min(max(t - self.t, 0.0) / VANE_AVERAGING_S, 1.0)
            self.mean = self.mean + weight * (unit - self.mean)
        self.t = t
        angle = math.degrees(math.atan2(self.mean[0], self.mean[1])) % 360.0
        if self.drawn_deg is not None and abs((angle - self.drawn_deg + 180.0) % 360.0 - 180.0) < REDRAW_DEG:
            return False
        self.drawn_deg = angle
        self.draws += 1
        origin, vector = wind_arrow(FarmGeometry(**{**self.geometry.__dict__, "wind_from_deg": angle}))
        rec.send_columns(
            WIND,
            indexes=[rr.TimeColumn(timeline, duration=[t])],
            columns=rr.Arrows2D.columns(
                origins=[origin],
                vectors=[vector],
                colors=[WIND_COLOUR],
                radii=[self.geometry.rotor_diameter_m / 8.0],
                labels=[f"wind from {angle:.0f}° (vane, {VANE_AVERAGING_S:.0f}-s mean)"],
                show_labels=[True],
            ).partition([1]),
        )
        return True


def turbine_states(turbine: np.ndarray, flags: np.ndarray, mode: np.ndarray, n_turbines: int) -> np.ndarray:
    """Index into ``STATES`` of turbines 1 … n_turbines from rows of the farm references (any order; a turbine
    without a row stays healthy)."""
    state = np.zeros(n_turbines, dtype=np.int8)
    flagged = np.asarray(flags, dtype=bool).reshape(len(turbine), -1).any(axis=1)
    mode = np.asarray(mode)
    row_state = np.where(np.isin(mode, DERATED_MODES), 2, np.where(flagged, 1, np.where(mode != 0, 3, 0))).astype(
        np.int8
    )
    index = np.asarray(turbine, dtype=int) - 1
    keep = (index >= 0) & (index < n_turbines)
    state[index[keep]] = row_state[keep]
    return state


class MapColours:
    """The supervisor's side: sends the colours of every turbine when one of them changes state."""

    def __init__(self, n_turbines: int):
        self.n_turbines = n_turbines
        self.last: np.ndarray | None = None
        self.changes = 0

    def update(self, rec: rr.RecordingStream, timeline: str, t: float, refs: np.ndarray) -> bool:
        """Log the colours at simulation time ``t`` if a state changed; True if it logged."""
        state = turbine_states(refs["turbine"], refs["flags"], refs["mode"], self.n_turbines)
        if self.last is not None and np.array_equal(state, self.last):
            return False
        self.last = state
        self.changes += 1
        rec.send_columns(
            TURBINES,
            indexes=[rr.TimeColumn(timeline, duration=[t])],
            columns=rr.Points2D.columns(colors=STATE_COLOURS[state]).partition([self.n_turbines]),
        )
        return True


def map_view() -> rrb.Spatial2DView:
    legend = ", ".join(f"{name} ({colour})" for name, colour in zip(STATES, COLOUR_NAMES, strict=True))
    return rrb.Spatial2DView(origin=MAP, name=f"farm map, north up: {legend}; the turbine tabs hold each turbine")
