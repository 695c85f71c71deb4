"""The explanations of the speed-sensor data an isolation chooses among (``fdi``, "Isolation").

An explanation is a set of speed sensors, as a bitmask in ``SPEED_SENSORS`` order, that some observer of the bank
leaves out (``BankDesign.left_out``). It is consistent when every one of its witnesses is: every observer that
leaves out at least its sensors (where the flags would be right), except the Kalman-form ones (their random walk of
the aerodynamic torque is too slow above rated to keep their residuals white there) unless it is the explanation's
own. The statistics come in as ratios to a level (χ²/h and the window sum over its threshold, the larger), one per
observer, so one test serves every level: detection, isolation, confirmation and the hold's α_iso/N.
"""

from __future__ import annotations

import numpy as np

from service.turbine.bank import GENERATOR, BankDesign
from service.turbine.bias_test import ROTOR
from wwcore.channels import SPEED_SENSORS

N_SPEED = len(SPEED_SENSORS)
BITS = 1 << np.arange(N_SPEED)
SENSORS_OF_MASK = (np.arange(1 << N_SPEED)[:, None] >> np.arange(N_SPEED)) & 1 == 1  # (16, 4): bitmask → flags
GENERATOR_BITS = sum(1 << SPEED_SENSORS.index(g) for g in GENERATOR)
ROTOR_BITS = sum(1 << r for r in ROTOR)


def mask_of(sensors: frozenset[str]) -> int:
    """The bitmask of a set of speed-sensor names."""
    return sum(1 << SPEED_SENSORS.index(s) for s in sensors)


class Explanations:
    """The bank's explanations (one per isolating observer j, ``masks[j]``), their witnesses and their choice."""

    def __init__(self, bank: BankDesign):
        masks = [mask_of(s) for s in bank.left_out]
        self.masks = np.array(masks)
        self.sizes = np.array([len(s) for s in bank.left_out])
        self.observer_of_mask = np.full(1 << N_SPEED, -1)  # bitmask → its observer j, −1 where none leaves it out
        for j, m in enumerate(masks):
            self.observer_of_mask[m] = j
        kinds = [o.kind for o in bank.observers[: bank.n_isolating]]
        # witnesses[k, j]: observer j must be consistent for explanation k (module docstring)
        self.witnesses = np.array(
            [
                [(mj & mk) == mk and (j == k or kinds[j] != "kalman") for j, mj in enumerate(masks)]
                for k, mk in enumerate(masks)
            ]
        ).astype(float)

    def explained(self, ratio: np.ndarray) -> np.ndarray:
        """For each explanation (observer index), the largest ratio among its witnesses (n_isolating,)."""
        return (self.witnesses * ratio).max(axis=1)

    def consistent(self, mask: int, ratio: np.ndarray) -> bool:
        """Whether the explanation ``mask`` has an observer and every witness of it within its level (``ratio``)."""
        j = self.observer_of_mask[mask]
        return bool(j >= 0 and (self.witnesses[j] * ratio).max() <= 1.0)

    @staticmethod
    def grows(held: int, explanation: int) -> bool:
        """Whether ``explanation`` keeps the sensors of ``held``, or of ``held`` with the other generator-speed
        sensor (the arbitration's choice stays open): a further fault beside the one a wait was on."""
        generator = held & GENERATOR_BITS
        other = held ^ GENERATOR_BITS if generator in (BITS[2], BITS[3]) else held
        return (explanation & held) == held or (explanation & other) == other

    def grown_by_chance(self, explanation: int, keep: int, current: int, detect: np.ndarray) -> bool:
        """Whether ``explanation`` grows a smaller one that keeps the ``keep`` sensors, names one beside the
        ``current`` flags and is consistent at the detection level (``detect``: ``explained``'s ratios at it). The
        choice takes the smallest explanation consistent at the isolation level, so the smaller one lost only by a
        witness between the isolation and the detection levels."""
        masks = self.masks
        smaller = ((masks & keep) == keep) & ((masks & explanation) == masks) & (masks != explanation)
        return bool((detect[smaller & (masks != current)] <= 1.0).any())

    def generator_alternative(self, explanation: int, isolate: np.ndarray, frozen: int = 0) -> int | None:
        """The same explanation with the other generator-speed sensor, if the residuals do not rule it out
        (consistent at the detection level, ``isolate`` being ``explained``'s ratios there: only the arbitration can
        tell a small fault's sensor) and the explanation's own generator-speed sensor is not ``frozen`` (a frozen
        reading is a fault whatever its value)."""
        generator = explanation & GENERATOR_BITS
        if generator not in (BITS[2], BITS[3]) or generator & frozen:
            return None
        other = explanation ^ GENERATOR_BITS
        j = self.observer_of_mask[other]
        return int(other) if j >= 0 and isolate[j] <= 1.0 else None

    def explain(
        self, current: int, ratio: np.ndarray, isolate: np.ndarray, frozen: int, own: np.ndarray
    ) -> tuple[int, bool]:
        """The smallest explanation of the data that keeps the ``current`` flags and the ``frozen`` sensors, and
        whether none was consistent (ambiguous): consistent when all its witnesses are (``ratio``, ``isolate``:
        ``explained`` at the detection and the isolation level); among consistent ones of one size, the one whose own
        observer's statistic (``own``, at the isolation level) is smallest, i.e. that leaves least of the data
        unexplained."""
        keep = current | frozen
        supersets = ((self.masks & keep) == keep) & (self.masks != current)
        with_frozen = ((self.masks & frozen) == frozen) & (self.masks != current)
        order = ((supersets, isolate), (supersets, ratio), (with_frozen, isolate), (with_frozen, ratio))
        for pool_mask, level in order:
            pool = np.flatnonzero(pool_mask & (level <= 1.0))
            if len(pool):
                return int(self.masks[pool[np.lexsort((own[pool], self.sizes[pool]))[0]]]), False
        # nothing explains the data: the flags grow (the smallest superset, least inconsistent), and where none is
        # left they stay; a flag drops only by its clearing test, never because no explanation fits a gust
        candidates = np.flatnonzero(supersets)
        if len(candidates) == 0:  # every sensor an observer can leave out is flagged or frozen already
            return keep, True
        return int(self.masks[candidates[np.lexsort((ratio[candidates], self.sizes[candidates]))[0]]]), True
