"""How the farm's FLORIS wake tables are built (``WakeSettings``) and where they are cached, without FLORIS.

A table built before with the same key (``cache_key``: the layout's positions and D, the settings, the installed
FLORIS's version and the table format) loads from ``<cache_dir>/wakes-<key>.npz`` here; only a missing or unusable
one needs ``plant_sim.farm.floris_wakes``, which imports FLORIS (about 0.65 CPU-s and 2 s of wall time a process on
the reference machine, paid by every process of an evaluation that imported it to load a cached table).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import logging
import math
import os
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from plant_sim.farm.wake_tables import FORMAT_VERSION, WakeTables
from wwcore.layout import FarmLayout
from wwcore.turbine_params import TurbineParams

log = logging.getLogger(__name__)


class WakeSettings(BaseModel):
    """How the wake tables are built (all of it goes into the cache key)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    model: Literal["gauss", "jensen"] = "gauss"
    turbulence_intensity: float = Field(default=0.10, gt=0.0, le=0.5, description="–, ambient TI of the free stream")
    direction_step_deg: float = Field(default=1.0, ge=0.1, le=5.0, description="deg, table step in wind direction")
    thrust_points: int = Field(default=8, ge=3, le=64, description="C_T grid points (uniform in 1 − √(1 − C_T))")
    thrust_max: float = Field(default=0.9, gt=0.5, lt=1.0, description="–, largest C_T tabulated (clipped above)")
    ti_points: int = Field(default=4, ge=2, le=32, description="TI grid points of the Gauss deficit")
    reference_speed_mps: float = Field(default=10.0, gt=0.0, le=40.0, description="m/s, of the 0.05 m/s threshold")
    min_deficit: float = Field(default=5e-4, ge=0.0, le=0.01, description="–, pairs below this δ and τ are dropped")
    sector_deg: tuple[float, float] | None = Field(
        default=None,
        description="deg, (from, to) clockwise: tabulate only the directions of this sector (None: all 360 deg)",
    )

    @field_validator("sector_deg")
    @classmethod
    def _sector(cls, value: tuple[float, float] | None) -> tuple[float, float] | None:
        if value is not None and not all(math.isfinite(v) and -360.0 <= v <= 720.0 for v in value):
            raise ValueError("sector_deg: two finite directions in degrees")
        return value

    def covered(self, directions_deg: np.ndarray) -> np.ndarray:
        """Which table directions the sector covers (with one table step either side)."""
        if self.sector_deg is None:
            return np.ones(len(directions_deg), dtype=bool)
        lo, hi = self.sector_deg
        if hi - lo >= 360.0:
            return np.ones(len(directions_deg), dtype=bool)
        width = (hi - lo) % 360.0 + 2.0 * self.direction_step_deg
        return (np.asarray(directions_deg) - lo + self.direction_step_deg) % 360.0 <= width


def cache_key(layout: FarmLayout, settings: WakeSettings, params: TurbineParams) -> str:
    """32 hex digits of the SHA-256 of what the tables depend on; FLORIS's version as its installed distribution
    says it (``floris.__version__``'s string, read without importing FLORIS)."""
    digest = hashlib.sha256()
    digest.update(layout.fingerprint())
    version = importlib.metadata.version("floris")
    identity = {"settings": settings.model_dump(), "hub": params.hub_height, "floris": version}
    digest.update(json.dumps({**identity, "format": FORMAT_VERSION}, sort_keys=True).encode())
    return digest.hexdigest()[:32]


def default_cache_dir() -> Path:
    """``$WINDWARDEN_CACHE/wakes`` or ``~/.cache/windwarden/wakes``."""
    root = os.environ.get("WINDWARDEN_CACHE")
    return Path(root) / "wakes" if root else Path.home() / ".cache" / "windwarden" / "wakes"


def cached_wake_tables(
    layout: FarmLayout, settings: WakeSettings, params: TurbineParams, cache_dir: Path | str | None = None
) -> tuple[str, Path, WakeTables | None]:
    """(key, cache file, the tables loaded from it, or None when there is none or it is unusable)."""
    if not math.isclose(layout.rotor_diameter, 2.0 * params.radius, rel_tol=1e-9):
        raise ValueError(f"layout resolved for D = {layout.rotor_diameter} m, the turbine's is {2 * params.radius} m")
    key = cache_key(layout, settings, params)
    path = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    file = path / f"wakes-{key}.npz"
    if file.is_file():
        try:
            return key, file, WakeTables.load(file, key)
        except (ValueError, OSError, KeyError) as exc:  # a damaged or foreign file: build again
            log.warning("wake table cache %s unusable (%s); rebuilding", file, exc)
    return key, file, None
