"""Print the hydrostatic supervisor's detection design for a scenario: the observer's noise response, the predicted
fault-free σ and worst case of f̂_a,filt, the thresholds the live supervisor and ``windwarden eval`` use, and
(``hold_offset``) when a flagged offset's correction becomes the mean of f̂_a and how noisy that mean is.

    .venv/bin/python tools/hydro_threshold.py hydro-fig9 hydro-noise

Nothing is simulated: the numbers follow from the observer's settings, the sensors' accuracy
(``sensor_noise_pct``) and the design false-alarm rate (``service.hydro.detector``, ``service.hydro.noise``).
"""

from __future__ import annotations

import sys

from service.hydro.offset_hold import mean_response_l2
from service.hydro.supervisor import HydroSupervisor
from wwcore.scenario import load_scenario


def describe(name: str) -> str:
    scenario = load_scenario(name)
    spec = scenario.supervisor
    sup = HydroSupervisor(n=1, observer=spec.estimator, detector=spec.detector, options=spec.params)
    lines = [f"{scenario.name}: observer {sup.observer_name!r}, detector {sup.detector_name!r}"]
    settings = getattr(sup.detector, "s", None)
    noise = getattr(sup.detector, "noise", None)
    if settings is not None and noise is not None:
        a = settings.sensor_noise_pct
        lines += [
            f"  noise response  ‖h‖₂ = {noise.l2[0]:.3f}, {noise.l2[1]:.3f}   "
            f"‖h‖₁ = {noise.l1[0]:.3f}, {noise.l1[1]:.3f}",
            f"  sensors ±{a:g} %  σ(f̂_filt) = {sup.detector.sigma[0]:.5f}, {sup.detector.sigma[1]:.5f}   "
            f"worst |f̂_filt| = {noise.worst(a)[0]:.5f}, {noise.worst(a)[1]:.5f}",
            f"  design rate {settings.false_alarms_per_1000s:g} per 1000 s, floor {settings.min_offset:g}",
        ]
    theta = sup.thresholds
    if theta is not None:
        lines.append(f"  θ [u_p, u_M] = {theta[0]:.5f}, {theta[1]:.5f}")
    if sup.hold is not None and settings is not None and noise is not None and noise.h_a is not None:
        scale = settings.sensor_noise_pct / 100.0 / 3.0**0.5
        after = {s: scale * mean_response_l2(noise.h_a, round(s / sup.context.dt))[0] for s in (1.0, 10.0)}
        lines.append(
            f"  flagged: the mean of f̂_a from {sup.hold.samples[0]} samples after the flag; its σ "
            + ", ".join(f"{v:.5f} at {k:g} s" for k, v in after.items())
        )
    return "\n".join(lines)


def main(names: list[str]) -> int:
    for name in names or ["hydro-fig9", "hydro-noise"]:
        print(describe(name))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
