"""Wind description of a scenario: a mean-speed profile plus turbulence, shear and tower shadow."""

from __future__ import annotations

import itertools

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
