"""The fault schedule of a scenario: one entry per fault, the same schema the API's injection route takes."""

from __future__ import annotations

from enum import StrEnum

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator


class FaultKind(StrEnum):
    """What a fault does. Sensor kinds act on a measured channel; the others on an actuator or subsystem."""

    FIXED = "fixed"  # the reading is replaced by ``value``
    GAIN = "gain"  # the reading (truth + noise) is multiplied by ``value``
    OFFSET = "offset"  # ``value`` is added to the reading (or to an actuator command)
    DRIFT = "drift"  # ``value`` per second is added, growing from the fault's start
    STUCK = "stuck"  # the reading holds its last value before the fault
    NOISE = "noise"  # the noise standard deviation is multiplied by ``value``
    PITCH_DYNAMICS = "pitch_dynamics"  # the actuator's ω_n and ζ change to ``omega_n``, ``zeta``
    PITCH_OFFSET = "pitch_offset"  # ``value`` degrees are added to the blade's actual pitch
    TORQUE_OFFSET = "torque_offset"  # ``value`` N m is added to the converter's torque reference
    EFFICIENCY = "efficiency"  # the drive-train efficiency becomes ``value``
    DEBRIS = "debris"  # aerodynamic efficiency multiplied by ``value`` (farm fault 1)
    DRIVETRAIN_WEAR = "drivetrain_wear"  # drive-train fault 3 of the farm (see plant_sim.farm)


SENSOR_FAULT_KINDS = frozenset(
    {FaultKind.FIXED, FaultKind.GAIN, FaultKind.OFFSET, FaultKind.DRIFT, FaultKind.STUCK, FaultKind.NOISE}
)


class FaultSpec(BaseModel):
    """One scheduled fault. Times in seconds of simulation time; ``end_s`` None means until the run ends."""

    model_config = ConfigDict(extra="forbid")

    target: str = Field(description="sensor channel (e.g. omega_r_m1) or component (e.g. pitch_actuator_2)")
    kind: FaultKind
    value: float | None = Field(default=None, description="size of the fault; its unit depends on kind and target")
    start_s: float = Field(ge=0.0, description="s, when the fault begins")
    end_s: float | None = Field(default=None, description="s, when it ends; omit for the rest of the run")
    ramp_s: float = Field(default=0.0, ge=0.0, description="s, linear ramp in and out (the benchmark's fault 7)")
    omega_n: float | None = Field(default=None, gt=0.0, le=100.0, description="rad/s, for pitch_dynamics")
    zeta: float | None = Field(default=None, gt=0.0, le=5.0, description="–, for pitch_dynamics")
    turbine: int = Field(default=1, ge=1, description="which turbine of the plant, 1-based")
    name: str | None = Field(default=None, description="label in scorecards; defaults to target:kind@start")

    @field_validator("end_s")
    @classmethod
    def _end_after_start(cls, end_s: float | None, info: ValidationInfo) -> float | None:
        start_s = info.data.get("start_s")
        if end_s is not None and start_s is not None and end_s <= start_s:
            raise ValueError(f"end_s ({end_s}) must be after start_s ({start_s})")
        return end_s

    @field_validator("ramp_s")
    @classmethod
    def _ramps_fit(cls, ramp_s: float, info: ValidationInfo) -> float:
        start_s, end_s = info.data.get("start_s"), info.data.get("end_s")
        if end_s is not None and start_s is not None and 2.0 * ramp_s > end_s - start_s:
            raise ValueError(f"ramp_s ({ramp_s}) leaves no room: ramps in and out must fit in the window")
        return ramp_s

    @property
    def label(self) -> str:
        return self.name or f"{self.target}:{self.kind.value}@{self.start_s:g}"

    def intensity(self, t: float) -> float:
        """Fault signal f(t) in [0, 1]: 0 outside the window, ramping linearly over ``ramp_s`` at each end."""
        end = float("inf") if self.end_s is None else self.end_s
        if t < self.start_s or t >= end:
            return 0.0
        if self.ramp_s <= 0.0:
            return 1.0
        return min(1.0, (t - self.start_s) / self.ramp_s, (end - t) / self.ramp_s)
