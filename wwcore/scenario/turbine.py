"""Plant section of a single-turbine scenario and the rules its faults must follow."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from wwcore.channels import SENSOR_INDEX, SENSORS, Component, noise_std
from wwcore.scenario.faults import SENSOR_FAULT_KINDS, FaultKind, FaultSpec
from wwcore.site import NoiseConvention, SiteInfo
from wwcore.turbine_params import BENCHMARK


class TurbinePlant(BaseModel):
    """The 4.8 MW benchmark turbine (PARAMETERS.md a)."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["turbine"] = "turbine"
    noise_convention: NoiseConvention = Field(
        default="sigma", description="read the benchmark's noise numbers as σ (papers) or as variances (Simulink)"
    )
    power_reference_w: float = Field(default=4.8e6, gt=0.0, le=4.8e6, description="W, P_r given to the controller")

    @property
    def n_turbines(self) -> int:
        return 1

    def site(self, dt: float = BENCHMARK.dt) -> SiteInfo:
        """What the supervisor may know of this turbine: its published parameters and sensor noise."""
        return SiteInfo(
            kind="turbine",
            turbines=(1,),
            dt=float(dt),
            rated_power_w=BENCHMARK.rated_power,
            noise_convention=self.noise_convention,
            sensor_sigma=sensor_sigma(self.noise_convention),
        )


def sensor_sigma(convention: NoiseConvention) -> dict[str, float]:
    """σ of every sensor channel's noise under ``convention`` (``channels.noise_std``)."""
    return {c.name: noise_std(c, convention) for c in SENSORS}


def check_turbine_fault(fault: FaultSpec, n_turbines: int) -> list[tuple[str, str]]:
    """Problems with one fault on a benchmark turbine, as (field, message) pairs; empty when it is valid."""
    problems: list[tuple[str, str]] = []
    if fault.turbine > n_turbines:
        problems.append(("turbine", f"turbine {fault.turbine} does not exist (the plant has {n_turbines})"))
    if fault.target in SENSOR_INDEX:
        problems += _check_sensor_fault(fault)
    elif fault.target in {c.value for c in Component}:
        problems += _check_component_fault(fault)
    else:
        problems.append(("target", f"unknown channel or component {fault.target!r}"))
    return problems


def _require_value(fault: FaultSpec, lo: float, hi: float, unit: str) -> list[tuple[str, str]]:
    if fault.value is None:
        return [("value", f"a {fault.kind.value} fault needs a value")]
    if not lo <= fault.value <= hi:
        return [("value", f"{fault.value} is outside the physical range {lo:g} … {hi:g} {unit}")]
    return []


def _check_sensor_fault(fault: FaultSpec) -> list[tuple[str, str]]:
    channel = SENSORS[SENSOR_INDEX[fault.target]]
    span = channel.hi - channel.lo
    match fault.kind:
        case FaultKind.FIXED:
            return _require_value(fault, channel.lo, channel.hi, channel.unit)
        case FaultKind.GAIN:
            return _require_value(fault, 0.0, 10.0, "(gain)")
        case FaultKind.OFFSET:
            return _require_value(fault, -span, span, channel.unit)
        case FaultKind.DRIFT:
            return _require_value(fault, -span / 10.0, span / 10.0, f"{channel.unit}/s")
        case FaultKind.NOISE:
            return _require_value(fault, 0.0, 100.0, "× σ")
        case FaultKind.STUCK:
            return [] if fault.value is None else [("value", "a stuck fault takes no value")]
    return [("kind", f"{fault.kind.value!r} is not a sensor fault; use one of {sorted(SENSOR_FAULT_KINDS)}")]


def _check_component_fault(fault: FaultSpec) -> list[tuple[str, str]]:
    component = Component(fault.target)
    pitch = {Component.PITCH_ACTUATOR_1, Component.PITCH_ACTUATOR_2, Component.PITCH_ACTUATOR_3}
    allowed: dict[FaultKind, set[Component]] = {
        FaultKind.PITCH_DYNAMICS: pitch,
        FaultKind.PITCH_OFFSET: pitch,
        FaultKind.TORQUE_OFFSET: {Component.CONVERTER},
        FaultKind.EFFICIENCY: {Component.DRIVETRAIN},
    }
    if component not in allowed.get(fault.kind, set()):
        kinds = sorted(k.value for k, comps in allowed.items() if component in comps)
        return [("kind", f"{fault.kind.value!r} cannot act on {component.value}; use one of {kinds}")]
    match fault.kind:
        case FaultKind.PITCH_DYNAMICS:
            problems = []
            if fault.omega_n is None:
                problems.append(("omega_n", "a pitch_dynamics fault needs omega_n (rad/s)"))
            if fault.zeta is None:
                problems.append(("zeta", "a pitch_dynamics fault needs zeta"))
            return problems
        case FaultKind.PITCH_OFFSET:
            return _require_value(fault, -10.0, 10.0, "deg")
        case FaultKind.TORQUE_OFFSET:
            return _require_value(fault, -1e4, 1e4, "N m")
        case FaultKind.EFFICIENCY:
            return _require_value(fault, 0.05, 1.0, "(efficiency)")
    return []
