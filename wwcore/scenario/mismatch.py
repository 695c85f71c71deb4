"""The ``[mismatch]`` section: how the simulated plant differs from the design model the supervisor uses.

Only the plant reads this section. The supervisor is built from ``[plant]`` and ``[supervisor]`` alone (batch:
``windwarden.evaluation``; live: ``RunInfo``), so it keeps its nominal model: the benchmark's parameters
(``wwcore.turbine_params.BENCHMARK``), the project's C_p/C_q surface (``wwcore.aero``) and the benchmark's sensor
noise. Without the section, or with an empty one, the plant is the design model, bit for bit.

Every quantity has a physical meaning, a unit and an allowed range (``LIMITS``, ``SENSOR_BIAS_TOLERANCE``);
``docs/turbine.md`` ("Model mismatch") gives the sources. A value outside its range is refused before anything
runs, naming the field. The section gives centre values; ``[mismatch.spread]`` gives half-widths of uniform
draws around them, one draw per turbine and Monte Carlo run from that turbine's own random stream
(``plant_sim.turbine.mismatch``); ``[[mismatch.turbines]]`` entries override the centre values of one turbine.
Centre ± spread must stay inside the range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field

from wwcore.channels import SENSOR_INDEX, SENSOR_NAMES, SENSORS


@dataclass(frozen=True)
class Limit:
    """Allowed range of one mismatch quantity, with its unit and physical meaning."""

    lo: float
    hi: float
    unit: str
    meaning: str


LIMITS: dict[str, Limit] = {
    "cp_scale": Limit(
        0.75, 1.05, "–", "C_p,plant(λ, β) = cp_scale · C_p,design(λ − tsr_shift, β): soiling, erosion, icing (< 1)"
    ),
    "tsr_shift": Limit(-1.0, 1.0, "–", "Δλ: the plant's C_p surface is the design's moved by Δλ in tip-speed ratio"),
    "air_density_kgm3": Limit(0.90, 1.45, "kg/m³", "air density ρ of the site (design model: 1.225)"),
    "drivetrain_stiffness_factor": Limit(0.7, 1.3, "–", "K_dt,plant / K_dt, torsional stiffness of the drive train"),
    "drivetrain_damping_ratio": Limit(
        0.0025, 0.05, "–", "damping ratio ζ of the drive train's torsion mode (design model: 0.0019)"
    ),
    "pitch_omega_n_rads": Limit(8.3, 13.9, "rad/s", "natural frequency ω_n of the pitch actuators (design: 11.11)"),
    "pitch_zeta": Limit(0.45, 0.8, "–", "damping ratio ζ of the pitch actuators (design: 0.6)"),
    "noise_scale": Limit(0.5, 3.0, "–", "sensor noise σ of the plant / the benchmark's σ the supervisor assumes"),
}
"""Range of every scalar mismatch quantity. Why these bounds: ``docs/turbine.md``, "Model mismatch"."""

SENSOR_BIAS_TOLERANCE: dict[str, float] = {
    "omega_r_m1": 0.004 * 2.0 * math.pi,  # rad/s, the benchmark's noise number (1.5 % of rated rotor speed)
    "omega_r_m2": 0.004 * 2.0 * math.pi,
    "omega_g_m1": 0.05,  # rad/s, the benchmark's noise number (0.03 % of rated generator speed)
    "omega_g_m2": 0.05,
    "v_hub_m": 0.5,  # m/s, the benchmark's noise number
    "beta_1_m1": 0.2,  # deg, the benchmark's noise number (below seed 001's 0.3 deg misalignment fault)
    "beta_1_m2": 0.2,
    "beta_2_m1": 0.2,
    "beta_2_m2": 0.2,
    "beta_3_m1": 0.2,
    "beta_3_m2": 0.2,
    "tau_g_m": 90.0,  # N m, the benchmark's noise number (0.3 % of rated torque)
    "p_g_m": 24e3,  # W, power transducer accuracy class 0.5 (IEC 61400-12-1): 0.5 % of rated power
}
"""Largest calibration bias |b| of each sensor channel, in the channel's unit (a constant added to every reading)."""

_SENSOR_UNITS = {c.name: c.unit for c in SENSORS}
SCALAR_FIELDS: tuple[str, ...] = tuple(LIMITS)
SPREAD_FIELDS: tuple[str, ...] = (*SCALAR_FIELDS, "sensor_bias_fraction")


def _field(description: str) -> object:
    return Field(default=None, description=description)


class MismatchValues(BaseModel):
    """Centre values of the plant's quantities; a field left out (None) is the design model's value."""

    model_config = ConfigDict(extra="forbid")

    cp_scale: float | None = _field("–, C_p of the plant over the design's (0.75 … 1.05)")
    tsr_shift: float | None = _field("–, shift Δλ of the plant's C_p surface in tip-speed ratio (−1 … 1)")
    air_density_kgm3: float | None = _field("kg/m³, air density at the site (0.90 … 1.45)")
    drivetrain_stiffness_factor: float | None = _field("–, K_dt of the plant over the design's (0.7 … 1.3)")
    drivetrain_damping_ratio: float | None = _field("–, damping ratio of the torsion mode (0.0025 … 0.05)")
    pitch_omega_n_rads: float | None = _field("rad/s, pitch actuators' natural frequency (8.3 … 13.9)")
    pitch_zeta: float | None = _field("–, pitch actuators' damping ratio (0.45 … 0.8)")
    noise_scale: float | None = _field("–, every sensor's noise σ over the benchmark's (0.5 … 3)")
    sensor_noise_scale: dict[str, float] = Field(
        default_factory=dict, description="sensor name → its noise σ over the benchmark's; replaces noise_scale"
    )
    sensor_bias: dict[str, float] = Field(
        default_factory=dict, description="sensor name → calibration bias in the sensor's unit, within tolerance"
    )


class MismatchSpread(BaseModel):
    """Half-widths of the uniform draws around the centre values, one draw per turbine and Monte Carlo run."""

    model_config = ConfigDict(extra="forbid")

    cp_scale: float = Field(default=0.0, description="–")
    tsr_shift: float = Field(default=0.0, description="–")
    air_density_kgm3: float = Field(default=0.0, description="kg/m³")
    drivetrain_stiffness_factor: float = Field(default=0.0, description="–")
    drivetrain_damping_ratio: float = Field(default=0.0, description="–")
    pitch_omega_n_rads: float = Field(default=0.0, description="rad/s, drawn per blade")
    pitch_zeta: float = Field(default=0.0, description="–, drawn per blade")
    noise_scale: float = Field(default=0.0, description="–, drawn per sensor")
    sensor_bias_fraction: float = Field(
        default=0.0, description="–, each sensor's bias drawn within ± this share of its tolerance (0 … 1)"
    )


class TurbineMismatch(MismatchValues):
    """Centre values of one turbine, overriding the section's (the fields it gives; the others are the section's)."""

    turbine: int = Field(ge=1, description="which turbine of the plant, 1-based")


class Mismatch(MismatchValues):
    """The ``[mismatch]`` section (module docstring)."""

    spread: MismatchSpread = Field(default_factory=MismatchSpread)
    turbines: list[TurbineMismatch] = Field(default_factory=list)

    def centre(self, turbine: int) -> MismatchValues:
        """The centre values of one turbine: the section's, with that turbine's entry over them."""
        values = MismatchValues(**{k: getattr(self, k) for k in MismatchValues.model_fields})
        for entry in self.turbines:
            if entry.turbine == turbine:
                given = {k: getattr(entry, k) for k in entry.model_fields_set if k != "turbine"}
                values = values.model_copy(update=given)
        return values

    def problems(self, n_turbines: int) -> list[tuple[str, str]]:
        """Every value outside its range, as (field path, message) pairs; empty when the section is valid."""
        found = _spread_problems(self.spread)
        found += _value_problems("mismatch", self, self.spread)
        seen: set[int] = set()
        for i, entry in enumerate(self.turbines):
            path = f"mismatch.turbines[{i}]"
            if entry.turbine > n_turbines:
                found.append(
                    (f"{path}.turbine", f"turbine {entry.turbine} does not exist (the plant has {n_turbines})")
                )
            if entry.turbine in seen:
                found.append((f"{path}.turbine", f"turbine {entry.turbine} has two entries"))
            seen.add(entry.turbine)
            found += _value_problems(path, entry, self.spread)
        return found


def _outside(value: float, spread: float, limit: Limit) -> bool:
    return not (limit.lo <= value - spread and value + spread <= limit.hi)


def _range_text(limit: Limit) -> str:
    unit = "" if limit.unit == "–" else f" {limit.unit}"
    return f"the allowed range {limit.lo:g} … {limit.hi:g}{unit} ({limit.meaning})"


def _spread_problems(spread: MismatchSpread) -> list[tuple[str, str]]:
    found = []
    for name in SPREAD_FIELDS:
        value = getattr(spread, name)
        if not (math.isfinite(value) and value >= 0.0):
            found.append((f"mismatch.spread.{name}", f"{value} must be a half-width ≥ 0"))
    if not spread.sensor_bias_fraction <= 1.0:
        found.append(("mismatch.spread.sensor_bias_fraction", f"{spread.sensor_bias_fraction} is above 1 (a share)"))
    return found


def _value_problems(path: str, values: MismatchValues, spread: MismatchSpread) -> list[tuple[str, str]]:
    found = []
    for name, limit in LIMITS.items():
        value = getattr(values, name)
        if value is None:
            continue
        half = getattr(spread, name) if math.isfinite(getattr(spread, name)) else 0.0
        if _outside(value, 0.0, limit):
            found.append((f"{path}.{name}", f"{value} is outside {_range_text(limit)}"))
        elif _outside(value, half, limit):
            found.append(
                (
                    f"{path}.{name}",
                    f"{value} ± spread {half:g} reaches {value - half:g} … {value + half:g}, "
                    f"outside {_range_text(limit)}",
                )
            )
    noise = LIMITS["noise_scale"]
    for sensor, value in values.sensor_noise_scale.items():
        where = f"{path}.sensor_noise_scale.{sensor}"
        if sensor not in SENSOR_INDEX:
            found.append((where, f"unknown sensor; one of {', '.join(SENSOR_NAMES)}"))
        elif _outside(value, spread.noise_scale if math.isfinite(spread.noise_scale) else 0.0, noise):
            found.append((where, f"{value} (± spread {spread.noise_scale:g}) is outside {_range_text(noise)}"))
    fraction = spread.sensor_bias_fraction if math.isfinite(spread.sensor_bias_fraction) else 0.0
    for sensor, value in values.sensor_bias.items():
        where = f"{path}.sensor_bias.{sensor}"
        if sensor not in SENSOR_INDEX:
            found.append((where, f"unknown sensor; one of {', '.join(SENSOR_NAMES)}"))
            continue
        tol = SENSOR_BIAS_TOLERANCE[sensor]
        unit = _SENSOR_UNITS[sensor]
        if not (math.isfinite(value) and abs(value) + fraction * tol <= tol * (1.0 + 1e-12)):
            drawn = f" with ± {fraction:g} × tolerance drawn around it" if fraction else ""
            found.append(
                (where, f"{value} {unit}{drawn} is outside the calibration tolerance ± {tol:g} {unit} of {sensor}")
            )
    return found
