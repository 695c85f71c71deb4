"""What the compiled backend's tests (``tests/test_fast_backend.py``, ``test_fast_kernels.py``,
``test_fast_backend_farm.py``) share: the seed, the tolerance and its comparison, and the turbine scenario with a
fault of every class the compiled path treats apart."""

from __future__ import annotations

import tomllib

import numpy as np

SEED = 6151  # fresh: nothing is tuned on it
RTOL = 1e-12

# 60 s with a fault of every class the fast path treats apart: speed-sensor fixed, gain and stuck (flags, isolation,
# clearing, the observer switch), a drifting anemometer, pitch-sensor offset (parity, weighted pitch), a pitch
# actuator's dynamics and the drive train's efficiency (the per-row step matrices), a converter offset and a noisy
# torque sensor; the mean wind crosses rated, so both control zones run.
FAULTY = """
name = "fast-backend-check"
duration_s = 60.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 10.0], [60.0, 13.5]]
turbulence_intensity = 0.12
[[faults]]
name = "generator sensor 2 fixed"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 12.0
end_s = 20.0
[[faults]]
name = "anemometer drift"
target = "v_hub_m"
kind = "drift"
value = 0.02
start_s = 8.0
[[faults]]
name = "rotor sensor 1 stuck"
target = "omega_r_m1"
kind = "stuck"
start_s = 24.0
end_s = 32.0
[[faults]]
name = "rotor sensor 2 gain"
target = "omega_r_m2"
kind = "gain"
value = 1.1
start_s = 36.0
end_s = 44.0
[[faults]]
name = "pitch sensor offset"
target = "beta_1_m1"
kind = "offset"
value = 2.0
start_s = 14.0
end_s = 30.0
[[faults]]
name = "pitch actuator dynamics"
target = "pitch_actuator_2"
kind = "pitch_dynamics"
omega_n = 3.42
zeta = 0.9
start_s = 30.0
end_s = 45.0
ramp_s = 5.0
[[faults]]
name = "drive train efficiency"
target = "drivetrain"
kind = "efficiency"
value = 0.92
start_s = 40.0
end_s = 55.0
[[faults]]
name = "converter offset"
target = "converter"
kind = "torque_offset"
value = 100.0
start_s = 46.0
end_s = 56.0
[[faults]]
name = "torque sensor noise"
target = "tau_g_m"
kind = "noise"
value = 3.0
start_s = 50.0
end_s = 58.0
"""


def assert_close(fast: np.ndarray, reference: np.ndarray, what: str) -> None:
    fast, reference = np.asarray(fast, dtype=float), np.asarray(reference, dtype=float)
    assert fast.shape == reference.shape, what
    assert np.array_equal(np.isnan(fast), np.isnan(reference)), what
    scale = np.nanmax(np.abs(reference)) if reference.size else 0.0
    diff = np.nan_to_num(np.abs(fast - reference))
    assert diff.max(initial=0.0) <= RTOL * max(scale, 1e-300), f"{what}: largest difference {diff.max():.3g}"


def at_half_speed(text: str) -> dict:
    """A scenario with every time (duration, wind points, fault starts, ends and ramps) halved and every drift
    doubled: each fault still starts and ends, in the same order, above and below rated, in half the ticks."""
    data = tomllib.loads(text)
    data["duration_s"] /= 2
    data["wind"]["mean"] = [[t / 2, v] for t, v in data["wind"]["mean"]]
    for fault in data["faults"]:
        for key in ("start_s", "end_s", "ramp_s"):
            if key in fault:
                fault[key] /= 2
        if fault["kind"] == "drift":
            fault["value"] *= 2
    return data
