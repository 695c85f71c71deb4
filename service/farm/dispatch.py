r"""The load-distributing farm dispatch of seed 001 (``dispatch``): eqs. (18)–(26) with their accommodation rules.

**Dispatch** (eqs. (18)–(19)): P_ref,t = P_avail,t / Σ P_avail · P_ref,farm, active only while
P_ref,farm < Σ P_avail (19); otherwise every turbine gets rated power (it produces what it can). P_avail comes from
eqs. (20)–(22) (``service.farm.available``).

**Accommodation** (eqs. (23)–(26) and their [PROPOSED] variants), for the turbines the detector flags when
accommodation is on: one rule per fault type, chosen by option (``service.farm.accommodation``,
``service.farm.hold``). Per sample the dispatch

1. takes the estimated 3P power ripple of cancelling turbines off the readings (D-29, ``service.farm.ripple``):
   it is not its power loop's to answer;
2. estimates P_avail (20)–(22) and lets each rule mark the turbines it acts on;
3. scales debris turbines' P_avail (23), derates by (26) to the headroom P_over (25), shares the demand (18),
   lets the drive-train rule fix a held turbine's part, and scales debris turbines' shares back (24);
4. trims the free turbines' references by the farm's power error (D-27, ``service.farm.power_loop``);
5. asks the free turbines for the opposite of the cancelling turbines' ripple (D-29).

**Held turbines** (``FarmSample.held``: a sharded supervisor's lost shard, ``docs/farm.md`` §2.5): the plant keeps
their last references P_held,h, so the dispatch counts them as fixed producers at the references it sent them last
and runs eqs. (18)–(26) over the served set S with the demand less theirs, P_ref,farm,S = pos(P_ref,farm − Σ_H
P_held,h): (19) P_ref,farm,S < Σ_S P_avail, (18) P_ref,t = P_avail,t/Σ_S P_avail · P_ref,farm,S, (25) P_over =
Σ_S P_avail − P_ref,farm,S, (26) on served turbines only; the trim on the served turbines' power error, the ripple
estimated on served turbines and cancelled by served ones. So the farm's references still add up to the demand
while the served turbines can make up the rest. With no turbine held every step is the one above, value for value.

With the compiled backend (``FarmContext.fast``) steps 2–5 but the pitch trim's and the ripple's own steps are one
kernel, ``service.farm.fast.dispatch_shares``, and eqs. (20)–(22) three (``AvailablePower``), the same numbers; the
rule objects below are the reference, and the hold-torque rule runs them in either backend.

The reasons and the development runs behind each choice are in ``docs/farm.md`` §2.3. Options (declared with
their ranges in ``service.farm.builtin``): ``accommodation_rule`` (``cancel``, ``hold-torque``, ``paper``),
``pitch_rule`` (``trim``, ``paper``), ``drivetrain_relief``, ``derate_floor``, ``hold_margin``, ``hold_reserve``,
``release_after_s``, ``trim_kp``, ``trim_ki``, ``trim_limit``, ``ripple_compensation`` (false turns the ripple's
estimate and compensation off: the power loop then answers the ripple) and ``ripple_share`` = s ∈ [0, 1]
(default 1: the free turbines are asked for s of the ripple's opposite, the estimate still taken off the readings).
"""

from __future__ import annotations

import numpy as np

from service.farm.accommodation import (
    DEBRIS_FACTOR,
    DRIVETRAIN,
    DRIVETRAIN_RELIEF,
    P_MIN_W,
    PITCH,
    AccommodationPlan,
    CancelRule,
    DebrisRule,
    DrivetrainRule,
    PaperDrivetrainRule,
    PitchDerateRule,
    PitchTrimRule,
    derate_to_headroom,
)
from service.farm.available import AvailablePower
from service.farm.hold import HOLD_MARGIN, HOLD_RESERVE, RELEASE_AFTER_S, HoldTorqueRule
from service.farm.interfaces import P_G, FarmContext, FarmSample
from service.farm.power_loop import TRIM_KI, TRIM_KP, TRIM_LIMIT, FarmPowerTrim
from service.farm.ripple import RippleCompensation
from service.plugins import AlgorithmOptionError
from wwcore.scenario.farm import FARM_DT_S

ROW_SUM_MAX = 128  # turbines per farm whose sums ``service.farm.fast.row_sum`` adds in numpy's order

ACCOMMODATION_RULES = ("cancel", "hold-torque", "paper")  # drive train; the first is the default
PITCH_RULES = ("trim", "paper")  # the first is the default


def _share_option(options: dict, name: str, default: float) -> float:
    """``options[name]`` (else ``default``) as a share in [0, 1]; an AlgorithmOptionError naming it otherwise."""
    value = options.get(name, default)
    try:
        share = float(value)
    except (TypeError, ValueError):
        share = float("nan")
    if not 0.0 <= share <= 1.0:
        raise AlgorithmOptionError(f"{name}: {value!r} is not a share in [0, 1]")
    return share


def _choice(options: dict, name: str, choices: tuple[str, ...]) -> str:
    """``options[name]`` (else the first of ``choices``); an AlgorithmOptionError naming it if not one of them."""
    value = str(options.get(name, choices[0]))
    if value not in choices:
        raise AlgorithmOptionError(f"{name}: {value!r} is not one of {', '.join(choices)}")
    return value


class Dispatch:
    """Eqs. (18)–(26) for ``farms`` farms of N turbines each (module docstring)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.context = context
        self.p = context.params
        self.n = context.n
        self.derate_floor = float(options.get("derate_floor", 0.0))  # share of its P_avail (26) leaves a turbine
        self.relief = _share_option(options, "drivetrain_relief", DRIVETRAIN_RELIEF)  # D-32
        self.rule = _choice(options, "accommodation_rule", ACCOMMODATION_RULES)
        self.pitch_rule = _choice(options, "pitch_rule", PITCH_RULES)
        self.available = AvailablePower(self.p, fast=context.fast_aero, kernels=context.fast)
        self.pitch = PitchTrimRule(self.n) if self.pitch_rule == "trim" else PitchDerateRule(self.n)
        self.drivetrain: DrivetrainRule
        if self.rule == "cancel":
            self.drivetrain = CancelRule(self.n, self.relief)
        elif self.rule == "hold-torque":
            self.drivetrain = HoldTorqueRule(
                self.p,
                self.n,
                self.available,
                margin=float(options.get("hold_margin", HOLD_MARGIN)),
                reserve=float(options.get("hold_reserve", HOLD_RESERVE)),
                release_after_s=float(options.get("release_after_s", RELEASE_AFTER_S)),
            )
        else:
            self.drivetrain = PaperDrivetrainRule(self.n)
        self.power_trim = FarmPowerTrim(
            context.farms,
            float(options.get("trim_kp", TRIM_KP)),
            float(options.get("trim_ki", TRIM_KI)),
            float(options.get("trim_limit", TRIM_LIMIT)),
        )
        ripple_share = _share_option(options, "ripple_share", 1.0)  # D-29: the part of the ripple the others cancel
        compensate = bool(options.get("ripple_compensation", True))
        self.ripple = RippleCompensation(self.p, self.n, ripple_share, context.turbines) if compensate else None
        self.p_ref = np.full(self.n, self.p.rated_power)  # W, the references sent last
        self.p_avail = np.zeros(self.n)  # W, eq. (22), before accommodation
        # wwcore.farm_frames.DISPATCH_MODES: normal, debris, derated (26), held torque, pitch trim, 3P cancelled
        self.mode = np.zeros(self.n, dtype=np.int8)
        self.held_power = np.zeros(context.farms)  # W, Σ_H P_held: the held turbines' references per farm
        self.served_demand = np.zeros(context.farms)  # W, P_ref,farm,S: the demand less theirs, shared over S
        # the compiled twin of ``step`` after P_avail (``service.farm.fast.dispatch_shares``; the hold-torque rule's
        # state stays numpy's, and so do farms of over 128 turbines, whose sums numpy splits): the rules by code,
        # 1 the default (cancel, trim), 2 the paper's
        compiled = self.rule != "hold-torque" and context.turbines <= ROW_SUM_MAX
        self._kernels = context.fast if compiled else None
        if self._kernels is not None:
            trim = self.power_trim
            self._consts = (
                context.turbines,
                self.derate_floor,
                self.relief,
                1 if self.rule == "cancel" else 2,
                1 if self.pitch_rule == "trim" else 2,
                float(self.p.rated_power),
                trim.enabled,
                trim.kp,
                trim.ki,
                trim.limit,
                FARM_DT_S,
                P_G,
                DEBRIS_FACTOR,
                P_MIN_W,
            )
            self._none_held = np.zeros(self.n, dtype=bool)

    def estimate_available(self, sample: FarmSample) -> np.ndarray:
        """Eqs. (20)–(22): P_avail,t (n,) in W."""
        return self.available.step(sample, self.p_ref)

    def step(self, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        """The references (n,) W answering ``sample``; ``faulty`` (n, 3) the flags to accommodate."""
        measured = sample
        if self.ripple is not None:
            sample = self.ripple.without_ripple(sample)
        self.p_avail = self.estimate_available(sample)
        if self._kernels is not None:
            return self._compiled_step(measured, sample, faulty)
        held = np.zeros(self.n, dtype=bool) if sample.held is None else sample.held
        held_farm = sample.per_farm(held)
        # the held turbines: fixed producers at the references sent them last, outside the sharing
        self.held_power = np.where(held_farm, sample.per_farm(self.p_ref), 0.0).sum(axis=1)
        avail = np.where(held_farm, 0.0, sample.per_farm(self.p_avail))
        flags = sample.per_farm(faulty)
        demand = np.maximum(sample.demand - self.held_power, 0.0)  # P_ref,farm,S: the served turbines' part
        self.served_demand = demand
        maximum = avail.sum(axis=1)  # the served turbines' theoretical maximum production, Σ_S P_avail (19)
        plan = AccommodationPlan.empty(avail.shape, self.derate_floor, held_farm)
        DebrisRule.mark(plan, flags)
        self.pitch.mark(plan, flags[:, :, PITCH], sample)
        self.drivetrain.mark(plan, flags[:, :, DRIVETRAIN], sample)
        avail = DebrisRule.available(plan, avail)  # eq. (23)
        over = avail.sum(axis=1) - demand  # eq. (25)
        avail = derate_to_headroom(plan, avail, over)  # eq. (26)
        active = demand < maximum  # the dispatch acts only below the farm's maximum production
        share = avail / np.maximum(avail.sum(axis=1), 1.0)[:, None] * demand[:, None]  # eq. (18)
        share = self.drivetrain.shares(plan, avail, demand, active, share)
        share = DebrisRule.share(plan, share)  # eq. (24)
        # beyond the maximum every turbine runs at rated, but one in the drive-train hold stays at its floor (D-30)
        refs = np.where(active[:, None], share, np.where(plan.hold, plan.floor, self.p.rated_power))
        if self.power_trim.enabled:
            refs = self.power_trim.apply(sample, refs, active, plan.free, self.held_power)
        refs = np.where(held, self.p_ref, np.clip(refs, 0.0, self.p.rated_power).reshape(-1))
        # a hold released at this sample goes out as mode 5 at once (with this sample's references, computed as held)
        plan.cancelled = self.drivetrain.cancelled(flags[:, :, DRIVETRAIN])
        self.mode = plan.mode()
        if self.ripple is not None:  # D-29: the cancelling turbines' 3P power ripple, cancelled by the free ones
            sources = (plan.hold | plan.cancelled) & ~held_farm  # a held turbine's power is not seen: not estimated
            self.ripple.step(measured, sources.reshape(-1), ~(sources | plan.derate | held_farm).reshape(-1))
        self.p_ref = refs
        return refs

    def _compiled_step(self, measured: FarmSample, sample: FarmSample, faulty: np.ndarray) -> np.ndarray:
        """``step`` after P_avail by ``dispatch_shares`` (``__init__``), the pitch trim's and the ripple's steps
        numpy's as in ``step``: the same numbers (``tests/test_fast_backend_farm.py``)."""
        n, farms = self.n, len(sample.demand)
        refs, mode = np.empty(n), np.empty(n, dtype=np.int8)
        self.held_power, self.served_demand = np.empty(farms), np.empty(farms)
        sources, free = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
        held = self._none_held if sample.held is None else np.ascontiguousarray(sample.held, dtype=bool)
        self._kernels.dispatch_shares(
            self.p_avail,
            self.p_ref,
            held,
            sample.held is not None,
            np.ascontiguousarray(faulty, dtype=bool),
            np.ascontiguousarray(sample.demand, dtype=float),
            np.ascontiguousarray(sample.scada, dtype=float),
            self.power_trim.integral,
            self._consts,
            (refs, mode, self.held_power, self.served_demand, sources, free),
        )
        if self.pitch_rule == "trim":
            self.pitch.trim.step(sample, faulty[:, PITCH])
        self.mode = mode
        if self.ripple is not None:
            self.ripple.step(measured, sources, free)
        self.p_ref = refs
        return refs

    @property
    def wind(self) -> np.ndarray | None:
        """(n,) m/s, w_est of eq. (20)."""
        return self.available.wind

    @property
    def held_torque(self) -> np.ndarray:
        """(n,) N m, S_max sent with a hold (NaN: none)."""
        return self.drivetrain.held_torque

    @property
    def pitch_trim(self) -> np.ndarray:
        """(n, 3) deg, the per-blade pitch trims asked of the turbines (D-28)."""
        return self.pitch.pitch_trim

    @property
    def ripple_power(self) -> np.ndarray:
        """(n,) complex W, the power phasor each turbine is asked to add (D-29); zeros without compensation."""
        return np.zeros(self.n, dtype=complex) if self.ripple is None else self.ripple.power

    @property
    def ripple_rate(self) -> np.ndarray:
        """(n,) rad/s, the frequency of ``ripple_power``."""
        return np.zeros(self.n) if self.ripple is None else self.ripple.rate
