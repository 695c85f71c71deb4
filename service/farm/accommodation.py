r"""The dispatch's accommodation rules: what a flagged turbine's share of the demand and its mode become.

Each rule marks, on an ``AccommodationPlan``, the turbines of its fault type it acts on and how; the dispatch
(``service.farm.dispatch``) applies the plan to eqs. (18)–(19) in one fixed order. The rules, with the reasons and
the development runs behind each in ``docs/farm.md`` §2.3:

* ``DebrisRule``, eqs. (23)–(24): a turbine flagged for debris only counts 0.97 P_avail in the sum of (18) and is
  sent P_ref/0.97, so it keeps making its share although its rotor lost 3 %.
* ``PitchTrimRule`` (option ``pitch_rule = "trim"``, the default, D-28) [PROPOSED]: a per-blade pitch trim turns the
  misaligned blade back to the others (``service.farm.pitch_trim``); the turbine keeps its power. Why not (26):
  derating left the rotor imbalance where it was and took the farm's reserve.
* ``PitchDerateRule`` (``pitch_rule = "paper"``): eq. (26).
* Drive train, option ``accommodation_rule``:

  - ``CancelRule`` (``cancel``, the default, D-31) [PROPOSED]: from the flag on the turbine runs its normal laws and
    its converter cancels the fault's 3P shaft torque (mode 5, D-C4). With ``drivetrain_relief`` = r > 0 (D-32) it
    is relieved: eq. (26) with the floor (1 − r) P_avail instead of P_min, so while the farm has headroom it gives
    up to r P_avail of its share, and casts a weaker wake on the rows behind it.
  - ``HoldTorqueRule`` (``hold-torque``, D-26b, with its release D-30; ``service.farm.hold``).
  - ``PaperDrivetrainRule`` (``paper``): eq. (26), the torque dropped to what 50 kW needs at unchanged speed.

**Eq. (26)** (``derate_to_headroom``): P_over = Σ P_avail − P_ref,farm (25) and P_avail,f = max(pos(P_avail − P_over),
floor), the floor P_min = 50 kW unless a rule sets another; then (18) with P_avail,f. D-26: with several such
turbines the headroom is shared out in turbine order, P_over shrinking by what each took. Option ``derate_floor``
[PROPOSED, off by default] never derates a turbine below that share of its own available power.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from service.farm.interfaces import FarmSample
from service.farm.pitch_trim import PitchTrim
from wwcore.farm_frames import CANCEL_3P_MODE, DEBRIS_MODE, DERATED_MODE, HOLD_TORQUE_MODE, PITCH_TRIM_MODE

DEBRIS_FACTOR = 0.97  # eqs. (23)–(24)
P_MIN_W = 50e3  # eq. (26)
DRIVETRAIN_RELIEF = 0.1  # –, share of its available power a flagged, cancelled drive train gives up, D-32 [PROPOSED]
DEBRIS, PITCH, DRIVETRAIN = 0, 1, 2  # columns of the detector's ``faulty``


@dataclass
class AccommodationPlan:
    """What the rules ask of each turbine; every field (farms, N)."""

    debris: np.ndarray  # bool: eqs. (23)–(24)
    trimmed: np.ndarray  # bool: pitch trim (D-28)
    derate: np.ndarray  # bool: eq. (26)
    relieved: np.ndarray  # bool: eq. (26) with the floor (1 − r) P_avail (D-32)
    hold: np.ndarray  # bool: held at its floor by speed (D-26b)
    cancelled: np.ndarray  # bool: normal laws with the fault's 3P torque cancelled (mode 5)
    floor: np.ndarray  # W, eq. (26)'s floor
    kept: np.ndarray  # –, the share of its own P_avail eq. (26) leaves a turbine at least
    held: np.ndarray  # bool: no shard commands it (``FarmSample.held``), a fixed producer outside the sharing

    @classmethod
    def empty(cls, shape: tuple[int, int], kept: float, held: np.ndarray | None = None) -> AccommodationPlan:
        """A plan of no rule yet; ``held`` (farms, N) the turbines the dispatch cannot command (None: none)."""

        def none() -> np.ndarray:
            return np.zeros(shape, dtype=bool)

        held = none() if held is None else held
        return cls(none(), none(), none(), none(), none(), none(), np.full(shape, P_MIN_W), np.full(shape, kept), held)

    @property
    def free(self) -> np.ndarray:
        """The turbines that may take more of the demand: the trim acts on them (a relieved one too, D-32); a held
        one is not."""
        return ~(self.derate | self.hold | self.held)

    def mode(self) -> np.ndarray:
        """(n,) int8 ``wwcore.farm_frames.DISPATCH_MODES``; where rules overlap, the later one here wins."""
        mode = np.where(self.debris, DEBRIS_MODE, 0)
        mode = np.where(self.trimmed, PITCH_TRIM_MODE, mode)
        mode = np.where(self.derate, DERATED_MODE, mode)
        mode = np.where(self.cancelled, CANCEL_3P_MODE, np.where(self.hold, HOLD_TORQUE_MODE, mode))
        return mode.astype(np.int8).reshape(-1)


class DebrisRule:
    """Eqs. (23)–(24) on the turbines flagged for debris and nothing else."""

    @staticmethod
    def mark(plan: AccommodationPlan, flags: np.ndarray) -> None:
        """``flags`` (farms, N, 3): the detector's verdict."""
        plan.debris = flags[:, :, DEBRIS] & ~(flags[:, :, PITCH] | flags[:, :, DRIVETRAIN])

    @staticmethod
    def available(plan: AccommodationPlan, avail: np.ndarray) -> np.ndarray:
        return np.where(plan.debris, DEBRIS_FACTOR * avail, avail)  # eq. (23)

    @staticmethod
    def share(plan: AccommodationPlan, share: np.ndarray) -> np.ndarray:
        return np.where(plan.debris, share / DEBRIS_FACTOR, share)  # eq. (24)


class PitchTrimRule:
    """D-28: the flagged turbines get a per-blade pitch trim and keep their share."""

    def __init__(self, n: int):
        self.trim = PitchTrim(n)

    def mark(self, plan: AccommodationPlan, flagged: np.ndarray, sample: FarmSample) -> None:
        plan.trimmed = flagged.copy()
        self.trim.step(sample, plan.trimmed.reshape(-1))

    @property
    def pitch_trim(self) -> np.ndarray:
        """(n, 3) deg, the per-blade trims asked of the turbines."""
        return self.trim.trim


class PitchDerateRule:
    """Eq. (26) on the turbines flagged for a pitch misalignment (the paper's rule); no trim."""

    def __init__(self, n: int):
        self.pitch_trim = np.zeros((n, 3))

    @staticmethod
    def mark(plan: AccommodationPlan, flagged: np.ndarray, sample: FarmSample) -> None:
        plan.derate |= flagged


class DrivetrainRule:
    """A drive-train rule: ``mark`` the flagged turbines on the plan; ``shares`` may fix their part of the demand
    after (18) (the hold does); ``cancelled`` says which run with their 3P torque cancelled once the shares are
    set; ``held_torque`` (n,) N m is the cap sent with a hold (NaN: none)."""

    def __init__(self, n: int):
        self.held_torque = np.full(n, np.nan)

    def mark(self, plan: AccommodationPlan, flagged: np.ndarray, sample: FarmSample) -> None:
        raise NotImplementedError

    def shares(
        self, plan: AccommodationPlan, avail: np.ndarray, demand: np.ndarray, active: np.ndarray, share: np.ndarray
    ) -> np.ndarray:
        return share

    def cancelled(self, flagged: np.ndarray) -> np.ndarray:
        return np.zeros_like(flagged)


class CancelRule(DrivetrainRule):
    """D-31 with the relief D-32 (module docstring): no hold, the fault's 3P cancelled from the flag on."""

    def __init__(self, n: int, relief: float = DRIVETRAIN_RELIEF):
        super().__init__(n)
        self.relief = relief  # r

    def mark(self, plan: AccommodationPlan, flagged: np.ndarray, sample: FarmSample) -> None:
        plan.relieved = flagged & (self.relief > 0.0)
        plan.kept = np.where(plan.relieved, 1.0 - self.relief, plan.kept)

    def cancelled(self, flagged: np.ndarray) -> np.ndarray:
        return flagged


class PaperDrivetrainRule(DrivetrainRule):
    """Eq. (26) on the turbines flagged for the drive-train fault: the paper's rule."""

    def mark(self, plan: AccommodationPlan, flagged: np.ndarray, sample: FarmSample) -> None:
        plan.derate |= flagged


def derate_to_headroom(plan: AccommodationPlan, avail: np.ndarray, over: np.ndarray) -> np.ndarray:
    """Eq. (26) on the derated and relieved turbines of ``avail`` (farms, N) W, given P_over (farms,) W of (25):
    P_avail,f = max(pos(P_avail − P_over), floor, min(kept · P_avail, P_avail)), the headroom shared out in turbine
    order (D-26). A held turbine is not derated (it keeps its reference). A new array; the others' P_avail
    unchanged."""
    avail = avail.copy()
    derated = (plan.derate | plan.relieved) & ~plan.held
    for t in np.flatnonzero(derated.any(axis=0)):  # turbine order (D-26)
        hit = derated[:, t]
        if hit.any():
            reduced = np.maximum(np.maximum(avail[:, t] - np.maximum(over, 0.0), 0.0), plan.floor[:, t])
            reduced = np.maximum(reduced, np.minimum(plan.kept[:, t] * avail[:, t], avail[:, t]))
            taken = np.where(hit, avail[:, t] - reduced, 0.0)
            avail[:, t] = np.where(hit, reduced, avail[:, t])
            over = over - taken
    return avail
