"""Options of the benchmark detector's component tests (``component_fdi.ComponentFDI``): the pitch-sensor parity, the
pitch-actuator GLR and the converter's CUSUMs, each ``component_<field>`` in a scenario's ``[supervisor.params]``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from wwcore.options import Bounds


@dataclass(frozen=True)
class ComponentSettings:
    """Options of the component tests, ``component_<field>`` in ``[supervisor.params]``; ``Bounds``: the range."""

    # design rate of each family of tests
    false_alarms_per_1000s: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.01
    clear_alpha: Annotated[float, Bounds(gt=0.0, lt=1.0)] = 0.01
    # design rate of pitch-sensor flags dropping while their fault persists (the clearing CUSUM's h)
    false_clears_per_1000s: Annotated[float, Bounds(ge=1e-6, le=10.0, unit="1/1000 s")] = 0.01
    # smallest fault size the pitch-sensor clearing CUSUM assumes, in σ of the parity
    clear_floor: Annotated[float, Bounds(ge=0.25, le=10.0, unit="σ")] = 1.0
    # memory of the pitch-sensor clearing CUSUM's fault-size estimate
    fault_memory_s: Annotated[float, Bounds(ge=0.01, le=60.0, unit="s")] = 0.5
    # ticks averaged by the pitch-sensor window test
    parity_window: Annotated[int, Bounds(ge=1, le=10_000, unit="ticks")] = 10
    # ticks of evidence the pitch-actuator GLR weighs (5 s: a few of the turbulence's pitch excursions)
    actuator_window: Annotated[int, Bounds(ge=1, le=10_000, unit="ticks")] = 500
    # shorter windows whose GLR may also clear an actuator flag (the pitch motion since the fault ended), each a
    # whole number of blocks below actuator_window; the false-clear budget is split over them and the full window
    actuator_clear_windows: Annotated[tuple[int, ...], Bounds(ge=1, le=10_000, unit="ticks")] = (100, 200)
    # offsets the converter's CUSUMs are designed for, in σ of τ_g,m (one two-sided CUSUM each; the smallest sets
    # the detection limit, m/2, and the largest the delay of large offsets, a few ticks)
    converter_shifts: Annotated[tuple[float, ...], Bounds(gt=0.0, le=100.0, unit="σ")] = (0.25, 0.5, 1.0, 2.0, 4.0)
    # smallest offset the converter's clearing CUSUM assumes, in σ of τ_g,m: a flag holds while the residual's mean
    # stays above half of it
    converter_clear_floor: Annotated[float, Bounds(gt=0.0, le=10.0, unit="σ")] = 0.25
    # memory of the converter clearing CUSUM's offset estimate: long beside the clearing (an offset is a constant;
    # a short memory forgets the offset as soon as it ends, and the CUSUM then tests for the floor alone)
    converter_memory_s: Annotated[float, Bounds(ge=0.01, le=3600.0, unit="s")] = 10.0
    # the actuator test decides every this many ticks, on every tick's residual (the converter's spread: per block)
    block: Annotated[int, Bounds(ge=1, le=1000, unit="ticks")] = 10
    frozen_ticks: Annotated[int, Bounds(ge=2, le=1000, unit="ticks")] = 3
    warmup_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = 5.0
    # adaptation time T_a of the residuals' healthy spread and offset (``adaptive``; 0: design thresholds, fixed)
    adapt_time_s: Annotated[float, Bounds(ge=0.0, le=3600.0, unit="s")] = 600.0
    # largest sensor-noise scale the adaptive thresholds accept
    max_noise_scale: Annotated[float, Bounds(ge=1.0, le=10.0)] = 3.0
