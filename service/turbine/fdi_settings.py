"""Options of the speed-sensor FDI (``service.turbine.fdi``), declared with their accepted ranges: the detector's
options in ``[supervisor.params]`` are this dataclass's fields (``wwcore.options``), refused before anything runs
when unknown or out of range, and the combinations the tests cannot run with are refused at construction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from service.plugins import AlgorithmOptionError
from service.turbine.uio import LAGS
from wwcore.options import Bounds


@dataclass(frozen=True)
class FDISettings:
    """Options of the speed-sensor FDI (``[supervisor.params]``); each field's ``Bounds`` is its accepted range."""

    # design rate of the detection tests (requirement: < 1, aim: none)
    false_alarms_per_1000s: Annotated[float, Bounds(ge=1e-6, le=10.0, unit="1/1000 s")] = 0.01
    # level at which an explanation (flagged set) is rejected when a fault is isolated
    isolation_alpha: Annotated[float, Bounds(ge=1e-9, le=0.1)] = 1e-3
    # design rate of flags dropping while their fault persists (clearing)
    false_clears_per_1000s: Annotated[float, Bounds(ge=1e-6, le=10.0, unit="1/1000 s")] = 0.01
    # smallest fault size the clearing CUSUM assumes, in σ of the exclusion residual
    clear_floor: Annotated[float, Bounds(ge=0.25, le=10.0, unit="σ")] = 1.0
    # memory of the clearing CUSUM's fault-size estimate
    fault_memory_s: Annotated[float, Bounds(ge=0.01, le=60.0, unit="s")] = 0.5
    # level of the re-admission test (observer using the sensor again, clear_window sum)
    clear_alpha: Annotated[float, Bounds(ge=1e-6, le=0.5)] = 0.01
    # time an isolation may wait for the generator-speed arbitration (0: take the smaller statistic)
    arbitration_s: Annotated[float, Bounds(ge=0.0, le=60.0, unit="s")] = 5.0
    window: Annotated[int, Bounds(ge=1, le=LAGS, unit="ticks")] = 4  # ticks summed by the window test
    # ticks of evidence gathered after a detection before isolating (< window)
    isolation_delay: Annotated[int, Bounds(ge=0, le=LAGS - 1, unit="ticks")] = 2
    # level at which a witness of the chosen explanation casts doubt on it: the decision then waits a tick
    isolation_confirm_alpha: Annotated[float, Bounds(ge=1e-9, le=0.5)] = 0.05
    # most ticks a doubtful isolation may wait beyond ``isolation_delay`` (0: decide at the deadline)
    isolation_patience: Annotated[int, Bounds(ge=0, le=100, unit="ticks")] = 5
    # ticks summed by the re-admission test (≤ window)
    clear_window: Annotated[int, Bounds(ge=1, le=LAGS, unit="ticks")] = 3
    # identical consecutive readings that mark a sensor frozen
    frozen_ticks: Annotated[int, Bounds(ge=2, le=1000, unit="ticks")] = 3
    # no decisions while the observers converge from their initial state
    warmup_s: Annotated[float, Bounds(ge=0.0, le=600.0, unit="s")] = 5.0
    # adaptation time T_a of each observer's healthy χ² scale (``adaptive``; 0: the design thresholds, fixed)
    adapt_time_s: Annotated[float, Bounds(ge=0.0, le=3600.0, unit="s")] = 600.0
    # largest sensor-noise scale the adaptive thresholds accept (their χ² scale is at most its square)
    max_noise_scale: Annotated[float, Bounds(ge=1.0, le=10.0)] = 3.0
    # Page's CUSUM for a persistent bias on one rotor-speed sensor, beside the window tests (``bias_test``)
    rotor_bias_test: bool = True  # on the rotor-speed parity: < 0.05 false alarms per 1000 s (docs/decisions.md)
    # the bias that CUSUM is designed for, m (it detects biases above m/2; > clear_floor, for hysteresis)
    bias_shift: Annotated[float, Bounds(ge=0.25, le=10.0, unit="σ")] = 1.5
    # the smallest bias on one rotor-speed sensor that a generator-speed explanation's sequential test against one
    # encoder is designed for (``rotor_pair``: it is decided alone only once a bias this large is unlikely)
    rotor_pair_shift: Annotated[float, Bounds(ge=0.25, le=10.0, unit="σ")] = 1.25
    # shifts in that CUSUM's bank: bias_shift·2^k, k < bias_bank (1: one CUSUM; more: larger biases found sooner)
    bias_bank: Annotated[int, Bounds(ge=1, le=6)] = 3

    def __post_init__(self) -> None:
        if self.isolation_delay >= self.window:
            raise AlgorithmOptionError(
                f"isolation_delay must be 0 … window − 1 ({self.window - 1}), not {self.isolation_delay}"
            )
        if self.isolation_confirm_alpha < self.isolation_alpha:
            raise AlgorithmOptionError(
                f"isolation_confirm_alpha ({self.isolation_confirm_alpha}) must be at least isolation_alpha "
                f"({self.isolation_alpha}): doubt is a laxer test than rejection"
            )
        if self.rotor_bias_test and self.bias_shift <= self.clear_floor:
            raise AlgorithmOptionError(
                f"bias_shift ({self.bias_shift}) must exceed clear_floor ({self.clear_floor}): a flag the bias test "
                "raises must not be dropped by the clearing for a fault the test would raise again (``bias_test``)"
            )
        if self.clear_window > self.window:
            raise AlgorithmOptionError(f"clear_window must be 1 … window ({self.window}), not {self.clear_window}")
