"""The farm supervisor's per-turbine status (``FarmKind.status``, twice a second on the loop's thread, 80 turbines
for Horns Rev 1), taken out of numpy column by column: the same entries as building each turbine's entry value by
value, with NaN and ±inf as null."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from windwarden.kinds import kind_for
from windwarden.kinds.base import finite_or_none
from wwcore.farm_frames import DISPATCH_MODES
from wwcore.scenario.farm import FARM_FAULT_TYPES
from wwcore.wire import FARM_REFS

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)


def _by_value(sup, refs, turbines):
    """Each turbine's entry built value by value, as the status is specified in ``docs/live.md``."""
    out = []
    for row, turbine in enumerate(turbines):
        entry = {
            "turbine": turbine,
            "flagged": [FARM_FAULT_TYPES[j] for j in range(3) if sup.flags[row][j]],
            "dispatch_mode": DISPATCH_MODES[int(sup.mode[row])],
            "detector": type(sup.detector).__name__,
            "margins": {name: finite_or_none(sup.diagnosis.margins[row][j]) for j, name in enumerate(FARM_FAULT_TYPES)},
            "power_ref_w": finite_or_none(sup.refs.power_ref[row]),
            "available_power_w": finite_or_none(sup.controller.p_avail[row]),
            "tick": int(refs[row]["tick"]),
        }
        out.append(entry)
    return out


def test_the_status_of_every_turbine_is_built_from_columns_with_non_finite_values_as_null():
    n = 80
    rng = np.random.default_rng(3)
    margins = rng.uniform(0, 3, (n, 3))
    margins[5, 1], margins[6, 2] = np.nan, np.inf
    power_ref = rng.uniform(0, 5e6, n)
    power_ref[7] = -np.inf
    flags = rng.uniform(size=(n, 3)) > 0.8
    supervisor = SimpleNamespace(
        diagnosis=SimpleNamespace(margins=margins),
        controller=SimpleNamespace(p_avail=rng.uniform(0, 5e6, n)),
        flags=flags,
        mode=rng.integers(0, len(DISPATCH_MODES), n),
        detector=SimpleNamespace(),
        refs=SimpleNamespace(power_ref=power_ref),
    )
    refs = FARM_REFS.empty(n)
    refs["tick"] = 1234
    turbines = list(range(1, n + 1))
    status = kind_for("farm").status(supervisor, refs, turbines)
    assert json.dumps(status) == json.dumps(_by_value(supervisor, refs, turbines))
    assert status[5]["margins"]["pitch_misalignment"] is None and status[7]["power_ref_w"] is None
    assert all(type(v) is float for v in status[0]["margins"].values())
