"""The supervisor: registry entries, detection events, the compensation switch and the step contract."""

from __future__ import annotations

import numpy as np
import pytest

from service.hydro.builtin import HydroContext
from service.hydro.detector import ThresholdDetector
from service.hydro.smo import Reconstruction
from service.hydro.supervisor import HydroSupervisor
from service.plugins import HYDRO_DETECTORS, HYDRO_OBSERVERS
from tests.hydro.conftest import offset, run_loop
from wwcore.events import EventType
from wwcore.hydro_frames import HydroRefs
from wwcore.hydro_params import NOMINAL
from wwcore.stepping import Plant, Supervisor


def _follows(obj: object, protocol: type) -> bool:
    """The members of a step-contract protocol (methods and attributes) are all present."""
    members = set(protocol.__annotations__) | {m for m in vars(protocol) if not m.startswith("_")}
    return all(hasattr(obj, m) for m in members)


def test_observers_and_detectors_are_registered_by_name():
    assert {"ts-smo", "none"} <= set(HYDRO_OBSERVERS.names())
    assert {"threshold", "none"} <= set(HYDRO_DETECTORS.names())


def test_detection_and_compensation(make_plant):
    faults = [offset("u_M", -0.15, 2.0, 5.0)]
    plant = make_plant(faults, n=2)
    sup = HydroSupervisor(n=2, params=plant.nominal, options={"tau_filter": [0.03, 0.03]})
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
    sup = HydroSupervisor(n=1, params=plant.nominal, observer="none", options={"tau_filter": [0.1, 0.1]})
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


def _rec(f_filt: np.ndarray) -> Reconstruction:
    n = f_filt.shape[0]
    return Reconstruction(f_filt, f_filt, np.zeros((n, 6)), np.ones(n, dtype=bool), np.zeros(n))


def test_detector_hysteresis():
    context = HydroContext(1, NOMINAL, "ts-smo")
    options = {"threshold": (0.05, 0.05), "on_samples": 3, "off_ratio": 0.5, "off_samples": 4}
    sup = HydroSupervisor(n=1, options=options)
    assert isinstance(sup.detector, ThresholdDetector) and sup.thresholds.tolist() == [0.05, 0.05]
    det = ThresholdDetector(context=context, options=options)
    trace = [0.0, 0.06, 0.06, 0.06, 0.04, 0.03, 0.02, 0.02, 0.02, 0.02, 0.0]
    flags = []
    for k, f in enumerate(trace):
        flags.append(bool(det.step(1.0 + 0.01 * k, _rec(np.array([[f, 0.0]])))[0, 0]))
    assert flags == [False, False, False, True, True, True, True, True, True, False, False]
    # nothing is flagged during the warm-up
    assert not ThresholdDetector(context=context, options=options).step(0.5, _rec(np.array([[1.0, 1.0]]))).any()
