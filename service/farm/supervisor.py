"""The farm supervisor: a detector and a farm controller chosen by name, composed into the step contract.

It runs on the plant's 10 Hz farm samples (``FarmFrame.sample``) and returns the same references in between.
Events: DETECTION / RECOVERY when a turbine's flag of one of the three faults changes (target = the fault type,
``wwcore.scenario.farm.FARM_FAULT_TYPES``), DISPATCH when a turbine's accommodation mode changes. Events carry
``run`` = the farm index of the batch (the evaluator maps farms to Monte Carlo runs and twins).

Turbines a sample says are ``held`` (a sharded supervisor's lost shard, ``FarmSample.held``) keep what the plant
keeps for them (``FarmKind.hold_unserved``), whatever the controller returns: the references answering the sample
carry their last power reference, mode, held torque and pitch trim, and no 3P ripple phasor; their mode does not
change, so no DISPATCH event is made up for them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from service.farm.interfaces import FarmContext, FarmDiagnosis, FarmSample
from service.farm.pitch_trim import TrimInReadings
from service.flag_events import flag_events, row_event
from service.plugins import FARM_CONTROLLERS, FARM_DETECTORS, choose
from wwcore.events import Event, EventType
from wwcore.farm_frames import CANCEL_3P_MODE, DISPATCH_MODES, HOLD_TORQUE_MODE, FarmFrame, FarmRefs
from wwcore.scenario.farm import FARM_FAULT_TYPES
from wwcore.site import SiteInfo
from wwcore.turbine_params import BENCHMARK, TurbineParams

DEFAULT_DETECTOR = FARM_DETECTORS.default
DEFAULT_CONTROLLER = FARM_CONTROLLERS.default


class FarmSupervisor:
    """Supervises ``n // N`` farms of the site's N turbines (rows farm-major; N and the positions from ``site``).

    ``backend`` (``wwcore.backend``; None: ``$WINDWARDEN_STEP_BACKEND``, else numpy): with ``"numba"`` the
    available-power estimate inverts the wind by ``wwcore.aero_fast`` (``FarmContext.fast_aero``), the same
    numbers.
    """

    def __init__(
        self,
        site: SiteInfo,
        n: int,
        *,
        detector: str | None = None,
        controller: str | None = None,
        accommodation: bool = True,
        options: dict | None = None,
        params: TurbineParams = BENCHMARK,
        backend: str | None = None,
    ):
        self.choice = choose("farm", options, detector=detector, controller=controller)  # refuses bad options
        self.context = FarmContext(site, n, params, backend=backend)
        names, chosen = self.choice.names, self.choice.options
        self.detector = FARM_DETECTORS.create(names["detector"], context=self.context, options=chosen["detector"])
        self.controller = FARM_CONTROLLERS.create(
            names["controller"], context=self.context, options=chosen["controller"]
        )
        self.accommodation = accommodation
        self.n = n
        self.dt = params.dt
        per_farm, farms = self.context.turbines, self.context.farms
        self.turbine_of_row = np.tile(np.arange(1, per_farm + 1), farms)
        self.farm_of_row = np.repeat(np.arange(farms), per_farm)
        self.flags = np.zeros((n, len(FARM_FAULT_TYPES)), dtype=bool)
        self.mode = np.zeros(n, dtype=np.int8)
        self.diagnosis: FarmDiagnosis | None = None
        self.sample: FarmSample | None = None
        self.refs: FarmRefs | None = None
        self.last_tick = -1  # tick of the last frame stepped
        self.trim_read = TrimInReadings(n, params)  # the trims sent, as the pitch readings carry them
        self._untrimmed_t: float | None = None  # time of the last sample the trim model was stepped for
        self._events: list[Event] = []

    def step(self, frame: FarmFrame) -> FarmRefs | None:
        """Refs answering tick ``frame.k``: new on farm samples, the last ones (re-stamped) in between."""
        self.last_tick = frame.k
        if not frame.sample:
            if self.refs is None:
                return None
            return replace(self.refs, tick=frame.k, computed_tick=self.refs.source_tick)
        sample = self.sample_of(frame)
        return self.decide(frame.k, sample, self.detector.step(sample))

    def sample_of(self, frame: FarmFrame) -> FarmSample:
        """The farm sample of ``frame`` as detector and controller are given it: a pitch trim this supervisor
        commanded is taken off the pitch readings."""
        return self.untrimmed(FarmSample.from_frame(frame, self.dt))

    def untrimmed(self, sample: FarmSample) -> FarmSample:
        """``sample`` with the pitch trims this supervisor sent taken off its pitch readings, as the readings carry
        them: through the blades' actuators and the sample's block mean (``pitch_trim.TrimInReadings``). Called
        once per sample (a second call for the same sample gives the same answer)."""
        if sample.t != self._untrimmed_t:
            self._untrimmed_t = sample.t
            self.trim_read.step(None if self.refs is None else self.refs.pitch_trim)
        read = self.trim_read.read
        return sample.untrimmed(read) if read.any() else sample

    def decide(self, tick: int, sample: FarmSample, diagnosis: FarmDiagnosis) -> FarmRefs:
        """The farm-wide part of a farm sample's step: the controller on the detector's ``diagnosis`` of
        ``sample``, the events, the references answering ``tick``. A sharded supervisor's coordinator calls it with
        the diagnosis its shards sent (``windwarden.live.coordinator``)."""
        self.last_tick = tick
        faulty = diagnosis.faulty if self.accommodation else np.zeros_like(diagnosis.faulty)
        power_ref = self.controller.step(sample, faulty)
        last = self.refs
        held = sample.held if sample.held is not None and sample.held.any() and last is not None else None
        self._record(sample.t, diagnosis, held)
        self.diagnosis, self.sample = diagnosis, sample
        refs = self._refs(tick, power_ref)
        self.refs = refs if held is None else self._kept(refs, last, held)  # held is None without last
        return self.refs

    def _refs(self, tick: int, power_ref: np.ndarray) -> FarmRefs:
        """The power references with what the controller asks of the turbines besides (``interfaces``)."""

        controller = self.controller

        def asked(name: str) -> np.ndarray | None:  # a copy of a controller attribute, None when it asks nothing
            value = getattr(controller, name, None)
            if value is None:
                return None
            value = np.asarray(value)
            return value.copy() if value.any() else None

        mode = None if getattr(controller, "mode", None) is None else self.mode  # as ``_record`` kept it
        hold = None if mode is None else mode == HOLD_TORQUE_MODE
        cancel = None if mode is None else mode == CANCEL_3P_MODE
        ripple = asked("ripple_power")
        return FarmRefs(
            tick=tick,
            power_ref=power_ref,
            hold_torque=hold,
            held_torque=asked("held_torque") if hold is not None and hold.any() else None,
            cancel_3p=cancel if cancel is not None and cancel.any() else None,
            pitch_trim=asked("pitch_trim"),
            ripple_power=ripple,
            ripple_rate=None if ripple is None else self.controller.ripple_rate.copy(),
        )

    @staticmethod
    def _kept(refs: FarmRefs, last: FarmRefs, held: np.ndarray) -> FarmRefs:
        """``refs`` with the ``held`` rows (n,) as the plant keeps them (``FarmKind.hold_unserved``): the ``last``
        references' power reference, held torque and pitch trim (the mode is kept by ``_record``), no ripple."""

        def kept(new: np.ndarray | None, old: np.ndarray | None, none: float) -> np.ndarray | None:
            if new is None and old is None:
                return None
            shape = (new if new is not None else old).shape
            new = np.full(shape, none) if new is None else new
            old = np.full(shape, none) if old is None else old
            value = np.where(held.reshape(-1, *([1] * (len(shape) - 1))), old, new)
            return value if np.any(value if none == 0.0 else ~np.isnan(value)) else None

        ripple = None if refs.ripple_power is None else np.where(held, 0.0, refs.ripple_power)
        asks_ripple = ripple is not None and ripple.any()
        return replace(
            refs,
            power_ref=np.where(held, last.power_ref, refs.power_ref),
            held_torque=kept(refs.held_torque, last.held_torque, np.nan) if refs.hold_torque is not None else None,
            pitch_trim=kept(refs.pitch_trim, last.pitch_trim, 0.0),
            ripple_power=ripple if asks_ripple else None,
            ripple_rate=np.where(held, 0.0, refs.ripple_rate) if asks_ripple else None,
        )

    def drain_events(self) -> list[Event]:
        events, self._events = self._events, []
        return events

    def _record(self, t: float, diagnosis: FarmDiagnosis, held: np.ndarray | None = None) -> None:
        """The events of a sample's verdict and the controller's modes; ``held`` rows (n,) keep their mode."""
        rows = self.turbine_of_row, self.farm_of_row
        raised = flag_events(t, self.flags, diagnosis.faulty, FARM_FAULT_TYPES, *rows)
        if raised:
            self._events += raised
            self.flags = diagnosis.faulty.copy()
        mode = getattr(self.controller, "mode", None)
        if mode is not None:
            if held is not None:
                mode = np.where(held, self.mode, mode).astype(np.int8)
            switched = mode != self.mode
            if switched.any():  # else ``self.mode`` (a copy) holds the same modes already
                for row in np.flatnonzero(switched):
                    detail = {"from": DISPATCH_MODES[int(self.mode[row])], "to": DISPATCH_MODES[int(mode[row])]}
                    self._events.append(row_event(t, EventType.DISPATCH, row, *rows, None, detail))
                self.mode = mode.copy()
