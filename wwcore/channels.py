"""Names of everything a fault can hit, with units and physical ranges.

The sensor channel names are part of the interface: scenario files, wire messages, scorecards and the API all
use them. Index order below is the column order of every sensor array (shape ``(n, N_SENSORS)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


@dataclass(frozen=True)
class SensorChannel:
    """One measured signal of the benchmark turbine (PARAMETERS.md a.3)."""

    name: str
    unit: str
    lo: float  # lowest physically meaningful reading, for validating fixed values
    hi: float  # highest physically meaningful reading
    noise_value: float  # the benchmark script's noise number (σ or variance, depending on the convention)
    noise_mean: float = 0.0  # a constant bias of the sensor (the anemometer has 1.5 m/s)
    quantity: str = ""  # the true signal the channel measures


SENSORS: tuple[SensorChannel, ...] = (
    SensorChannel("omega_r_m1", "rad/s", 0.0, 5.0, 0.004 * 6.283185307179586, quantity="omega_r"),
    SensorChannel("omega_r_m2", "rad/s", 0.0, 5.0, 0.004 * 6.283185307179586, quantity="omega_r"),
    SensorChannel("omega_g_m1", "rad/s", 0.0, 400.0, 0.05, quantity="omega_g"),
    SensorChannel("omega_g_m2", "rad/s", 0.0, 400.0, 0.05, quantity="omega_g"),
    SensorChannel("v_hub_m", "m/s", 0.0, 60.0, 0.5, noise_mean=1.5, quantity="v_hub"),
    SensorChannel("beta_1_m1", "deg", -10.0, 95.0, 0.2, quantity="beta_1"),
    SensorChannel("beta_1_m2", "deg", -10.0, 95.0, 0.2, quantity="beta_1"),
    SensorChannel("beta_2_m1", "deg", -10.0, 95.0, 0.2, quantity="beta_2"),
    SensorChannel("beta_2_m2", "deg", -10.0, 95.0, 0.2, quantity="beta_2"),
    SensorChannel("beta_3_m1", "deg", -10.0, 95.0, 0.2, quantity="beta_3"),
    SensorChannel("beta_3_m2", "deg", -10.0, 95.0, 0.2, quantity="beta_3"),
    SensorChannel("tau_g_m", "N m", -1e5, 1e5, 90.0, quantity="tau_g"),
    SensorChannel("p_g_m", "W", -1e7, 1e7, 1e3, quantity="p_g"),
)

SENSOR_NAMES: tuple[str, ...] = tuple(c.name for c in SENSORS)
SENSOR_INDEX: dict[str, int] = {name: i for i, name in enumerate(SENSOR_NAMES)}
N_SENSORS = len(SENSORS)

SPEED_SENSORS: tuple[str, ...] = ("omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2")
"""The four speed sensors whose faults the fault-tolerant estimator isolates and accommodates (seed 000)."""


class Component(StrEnum):
    """Actuators and subsystems that actuator/system faults can hit."""

    PITCH_ACTUATOR_1 = "pitch_actuator_1"
    PITCH_ACTUATOR_2 = "pitch_actuator_2"
    PITCH_ACTUATOR_3 = "pitch_actuator_3"
    CONVERTER = "converter"
    DRIVETRAIN = "drivetrain"


DIAGNOSIS_TARGETS: tuple[str, ...] = SENSOR_NAMES + tuple(c.value for c in Component)
"""Everything a turbine detector can flag: the sensor channels, then the components."""
TARGET_INDEX: dict[str, int] = {name: i for i, name in enumerate(DIAGNOSIS_TARGETS)}


def noise_std(channel: SensorChannel, convention: str) -> float:
    """Standard deviation of a channel's noise under a convention (PARAMETERS.md a.3).

    ``"sigma"`` reads the script's number as σ (the papers' reading, our default); ``"variance"`` reads it as a
    variance, σ = √value, as the benchmark's Simulink *Random Number* blocks do.
    """
    if convention == "sigma":
        return channel.noise_value
    if convention == "variance":
        return channel.noise_value**0.5
    raise ValueError(f"unknown noise convention {convention!r}; expected 'sigma' or 'variance'")
