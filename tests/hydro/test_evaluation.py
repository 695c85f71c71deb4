"""The evaluator's building blocks: results independent of chunking, metric definitions on known signals."""

from __future__ import annotations

import numpy as np
import pytest

from windwarden.evaluation.hydro import simulate
from windwarden.evaluation.hydro_scoring import reconstruction_metrics
from wwcore.scenario import parse_scenario

DATA = {
    "name": "chunks",
    "duration_s": 3.0,
    "plant": {"kind": "hydro"},
    "wind": {"mean": [[0.0, 7.5]], "turbulence_intensity": 0.15, "length_scale_m": 340.0},
    "faults": [{"target": "u_M", "kind": "offset", "value": -0.2, "start_s": 1.0, "end_s": 2.5}],
}


def test_results_do_not_depend_on_chunking():
    scenario = parse_scenario(DATA)
    both = simulate(scenario, [0, 1], 9)
    alone = simulate(scenario, [1], 9)
    for variant in ("compensated", "uncompensated", "fault_free"):
        for name in ("omega_g", "f_filt", "P_g"):
            assert np.array_equal(both[variant][name][:, 1], alone[variant][name][:, 0])
        assert [e for e in both["events"][variant] if e.run == 1] == alone["events"][variant]
    # twins share wind and noise: identical until the fault starts, different after
    k = 100
    assert np.array_equal(both["compensated"]["omega_g"][:k], both["fault_free"]["omega_g"][:k])
    assert not np.array_equal(both["uncompensated"]["omega_g"][k + 10], both["fault_free"]["omega_g"][k + 10])
    # the supervisor's own events: the fault on u_M detected in both faulty twins of both runs, none fault-free
    for variant in ("compensated", "uncompensated"):
        detections = sorted((e.run, e.target) for e in both["events"][variant] if e.type == "detection")
        assert detections == [(0, "u_M"), (1, "u_M")]
    assert both["events"]["fault_free"] == []


def test_reconstruction_metrics_on_a_known_signal():
    scenario = parse_scenario(DATA)
    ticks = 300
    f_true = np.zeros((ticks, 1, 2), dtype=np.float32)
    f_true[100:250, 0, 1] = -0.2
    f_filt = f_true.copy()
    f_filt[100:150, 0, 1] = -0.1  # half the size for the first 0.5 s, then exact but 2 % short
    f_filt[150:250, 0, 1] = -0.196
    (m,) = reconstruction_metrics({"f_true": f_true, "f_filt": f_filt}, scenario, 0.01)
    assert m["settle_s"] == pytest.approx(0.5)
    assert m["error_pct"] == pytest.approx(2.0, rel=1e-4)  # measured from 1 s after the start
