"""Wind description of a scenario: a mean-speed profile plus turbulence, shear and tower shadow; and the helpers of a
farm's wind-direction profile (``FarmPlant.wind_direction_profile``)."""

from __future__ import annotations

import itertools
import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator


class WindSpec(BaseModel):
    """Hub-height wind. The mean is piecewise linear through ``mean`` points [(t_s, v_mps), ...]."""

    model_config = ConfigDict(extra="forbid")

    mean: list[tuple[float, float]] = Field(
        default=[(0.0, 9.0)], description="[(t in s, mean speed in m/s)], piecewise linear, held after the last point"
    )
    turbulence_intensity: float = Field(default=0.12, ge=0.0, le=0.5, description="–, σ_u / mean (a.5: 0.12)")
    length_scale_m: float = Field(default=600.0, gt=0.0, le=5000.0, description="m, Kaimal length scale L")
    shear_exponent: float = Field(default=0.1, ge=0.0, le=0.5, description="–, power-law α (a.5: 0.1)")
    tower_shadow: bool = Field(default=True, description="Dolan–Lehn tower shadow on each blade")

    @field_validator("mean")
    @classmethod
    def _check_mean(cls, points: list[tuple[float, float]]) -> list[tuple[float, float]]:
        if not points:
            raise ValueError("needs at least one (t, v) point")
        times = [t for t, _ in points]
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError("times must increase strictly")
        if times[0] < 0.0:
            raise ValueError("times must be ≥ 0")
        for _, v in points:
            if not 0.5 <= v <= 40.0:
                raise ValueError(f"mean speed {v} m/s is outside 0.5–40 m/s")
        return points


# ---- wind direction over time (farm scenarios) ------------------------------------------------------------------
def check_direction_points(points: list[tuple[float, float]]) -> None:
    """Refuse a direction profile [(t in s, deg from north)] that ``unwrap_direction_points`` cannot read, with a
    message naming the point: times ≥ 0 and strictly increasing, directions finite in 0 … <360°, and no two
    consecutive directions exactly opposite (180° apart: the turn's sense is ambiguous)."""
    if not points:
        raise ValueError("needs at least one (t_s, deg) point")
    times = [t for t, _ in points]
    if not all(math.isfinite(t) for t in times) or times[0] < 0.0:
        raise ValueError("times must be finite and ≥ 0")
    if any(b <= a for a, b in itertools.pairwise(times)):
        raise ValueError("times must increase strictly")
    for t, deg in points:
        if not (math.isfinite(deg) and 0.0 <= deg < 360.0):
            raise ValueError(f"direction {deg} deg at t = {t} s is outside 0 … <360 deg")
    for (t0, a), (t1, b) in itertools.pairwise(points):
        if math.isclose(abs((b - a) % 360.0), 180.0, abs_tol=1e-9):
            raise ValueError(
                f"the directions at t = {t0} s and t = {t1} s are 180 deg apart: the sense of the turn is "
                "ambiguous; add a point in between"
            )


def unwrap_direction_points(points: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """(times s, unwrapped directions deg) of a direction profile: each point joined to the previous one along the
    shorter arc (350° then 10° is a veer of +20°, read as 370°), the first direction as given (0 … <360°)."""
    times = np.array([t for t, _ in points], dtype=float)
    degrees = np.array([d for _, d in points], dtype=float)
    steps = (np.diff(degrees) + 180.0) % 360.0 - 180.0  # −180 … <180, the shorter arc
    return times, np.concatenate([degrees[:1], degrees[0] + np.cumsum(steps)])


def direction_at(points: list[tuple[float, float]], t: np.ndarray | float) -> np.ndarray:
    """The profile's direction (deg, unwrapped: may leave 0 … 360) at times ``t``: linear between points on the
    unwrapped angles, the first direction before the first point, the last after the last."""
    times, degrees = unwrap_direction_points(points)
    return np.interp(np.asarray(t, dtype=float), times, degrees)
