"""The supervisor: registry entries, detection events, the compensation switch and the step contract."""

from __future__ import annotations

import numpy as np
import pytest

from service.hydro.detector import DetectionSettings, OffsetDetector, threshold_from_quiet
from service.hydro.supervisor import HydroSupervisor
from service.plugins import HYDRO_OBSERVERS
from tests.hydro.conftest import offset, run_loop
from wwcore.events import EventType
from wwcore.hydro_frames import HydroRefs
from wwcore.stepping import Plant, Supervisor


def _follows(obj: object, protocol: type) -> bool:
    """The members of a step-contract protocol (methods and attributes) are all present."""
    members = set(protocol.__annotations__) | {m for m in vars(protocol) if not m.startswith("_")}
    return all(hasattr(obj, m) for m in members)


def test_observers_are_registered_by_name():
    assert {"ts-smo", "none"} <= set(HYDRO_OBSERVERS.names())


def test_detection_and_compensation(make_plant):
    faults = [offset("u_M", -0.15, 2.0, 5.0)]
    plant = make_plant(faults, n=2)
    sup = HydroSupervisor(n=2, params=plant.nominal, observer_params={"tau_filter": [0.03, 0.03]})
    assert _follows(plant, Plant) and _follows(sup, Supervisor)
    free = run_loop(make_plant([], n=2), None, 8.0)
    out = run_loop(plant, sup, 8.0)
    events = sup.drain_events()
    det = [e for e in events if e.type is EventType.DETECTION]
    rec = [e for e in events if e.type is EventType.RECOVERY]
    assert sorted(e.run for e in det) == [0, 1] and all(e.target == "u_M" for e in det)
    assert all(2.0 <= e.t < 2.3 for e in det)
    assert all(5.0 <= e.t < 6.5 for e in rec) and len(rec) == 2
    unc = run_loop(make_plant(faults, n=2), HydroSupervisor(n=2, compensation=False), 8.0)
    dev_comp = np.abs(out["x"][:, :, 1] - free["x"][:, :, 1]).max()
    dev_unc = np.abs(unc["x"][:, :, 1] - free["x"][:, :, 1]).max()
    assert dev_unc > 10.0 and dev_comp < 0.2 * dev_unc  # the virtual actuator removes most of the deviation


def test_none_observer_switches_compensation_off(make_plant):
    plant = make_plant([offset("u_M", -0.15, 1.0, None)], n=1)
    sup = HydroSupervisor(n=1, params=plant.nominal, observer="none", observer_params={"tau_filter": [0.1, 0.1]})
    run_loop(plant, sup, 3.0)
    refs = sup.step(plant.measure())
    assert isinstance(refs, HydroRefs)
    assert not refs.apply.any() and np.all(refs.correction == 0.0)
    assert sup.drain_events() == []


def test_compensation_flag_is_per_turbine(make_plant):
    plant = make_plant([offset("u_p", -0.2, 1.5, None)], n=2)
    sup = HydroSupervisor(n=2, params=plant.nominal, compensation=np.array([True, False]))
    run_loop(plant, sup, 3.0)
    refs = sup.step(plant.measure())
    assert refs.apply.tolist() == [True, False]
    assert refs.correction[:, 0] == pytest.approx([-0.2, -0.2], rel=0.05)  # both reconstruct
    assert plant.u_sent[0, 0] > 1.15 and plant.u_sent[1, 0] <= 1.0  # only turbine 0 corrects its command


def test_detector_hysteresis_and_threshold_rule():
    settings = DetectionSettings(threshold=(0.05, 0.05), on_samples=3, off_ratio=0.5, off_samples=4)
    det = OffsetDetector(1, [7], settings)
    trace = [0.0, 0.06, 0.06, 0.06, 0.04, 0.03, 0.02, 0.02, 0.02, 0.02, 0.0]
    for k, f in enumerate(trace):
        det.step(1.0 + 0.01 * k, np.array([[f, 0.0]]))
    events = det.drain()
    assert [(e.type, round(e.t, 2), e.run, e.target) for e in events] == [
        (EventType.DETECTION, 1.03, 7, "u_p"),
        (EventType.RECOVERY, 1.09, 7, "u_p"),
    ]
    assert threshold_from_quiet(np.array([0.002, 0.02])) == pytest.approx((0.01, 0.03))
