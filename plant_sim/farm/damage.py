r"""Damage measures of the farm (PARAMETERS.md b: the benchmark's damage numbers are not available; ours).

**Drive-train fatigue.** The torque in the low-speed shaft, τ_s = K_dt (θ_Δ − e(ψ)) + B_dt (ω_r − ω_g/N_g)
(``TurbineBatch.shaft_torque``, 100 Hz truth), is reduced online to its turning points (``ReversalRecorder``;
reversals smaller than ``GATE_NM`` are filtered out, the usual hysteresis gate of fatigue practice: a cycle of
30 kN m carries 8e-8 of the damage of a 1 MN m cycle at m = 4; on the shipped farm the DEL moves by 0.06–0.15 %
against a 10 kN m gate while the turning points, and the rainflow time, drop 2.5-fold). The turning points are
rainflow counted (ASTM E1049 as the maintained ``rainflow`` package counts it; half cycles count ½), as the run goes
and in bounded memory by ``rainflow_stream.StreamingDamage``, equal bit for bit to ``damage_sums`` here, which
counts a whole sequence with the package itself and is the reference the tests compare with. The damage-equivalent
load at N_eq = 1 cycle per second over the span T is

.. math::  \mathrm{DEL} = \Bigl(\frac{1}{T}\sum_i n_i S_i^{m}\Bigr)^{1/m},\qquad m = 4 \text{ (Wöhler exponent)}

Miner's damage is proportional to Σ n_i S_i^m = T · DEL^m, so ``damage_sums`` keeps those sums per time bin and
a DEL over any span is built from them. The *damage number* of a run is its DEL divided by the DEL of the
fault-free twin (same wind, noise and controller, no faults): 1 for the fault-free run by construction.

**Rotor imbalance** (pitch misalignment). Blade i's aerodynamic torque τ_r,i in the rotating frame, summed as a
phasor, Σ_i τ_r,i e^{j2π(i−1)/3}, averages to zero for a symmetric rotor (each blade passes the same azimuths);
its mean over a span, |⟨Σ_i τ_r,i e^{j2π(i−1)/3}⟩|, is the 1P imbalance torque (N m) a misaligned blade leaves.
Normalised by the fault-free twin it is large (the paper's Table 7 reports inf): we report it in N m as well.
"""

from __future__ import annotations

import itertools

import numpy as np
import rainflow

WOHLER_M = 4.0  # –, Wöhler exponent of the drive train (PARAMETERS.md b)
GATE_NM = 3.0e4  # N m, smallest reversal kept (1 % of the rated shaft torque 2.96 MN m)
BLADE_PHASOR = np.exp(2j * np.pi * np.arange(3) / 3.0)  # e^{j2π(i−1)/3}


class ReversalRecorder:
    """Turning points of n signals sampled every tick, with a hysteresis gate, kept for rainflow counting."""

    def __init__(self, n: int, gate: float = GATE_NM):
        self.n = n
        self.gate = gate
        self.extreme: np.ndarray | None = None
        self.rising = np.ones(n, dtype=bool)
        self._ticks: list[np.ndarray] = []
        self._rows: list[np.ndarray] = []
        self._values: list[np.ndarray] = []

    def step(self, k: int, x: np.ndarray) -> None:
        if self.extreme is None:
            self.extreme = x.copy()
            self._record(k, np.arange(self.n), x)  # the first sample opens every sequence
            return
        ext, up = self.extreme, self.rising
        turn = np.where(up, ext - x > self.gate, x - ext > self.gate)
        if turn.any():
            rows = np.flatnonzero(turn)
            self._record(k - 1, rows, ext[rows])  # the extreme before x (its tick is approximate: the last one)
        further = np.where(up, x > ext, x < ext)
        self.extreme = np.where(turn | further, x, ext)
        self.rising = up ^ turn

    def finish(self, k: int) -> None:
        """Close every sequence with its last extreme."""
        if self.extreme is not None:
            self._record(k, np.arange(self.n), self.extreme)

    def _record(self, k: int, rows: np.ndarray, values: np.ndarray) -> None:
        self._ticks.append(np.full(len(rows), k, dtype=np.int64))
        self._rows.append(rows.astype(np.int32))
        self._values.append(values.astype(np.float64))

    def drain(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """``sequences()`` of the turning points recorded since the last call, which are then forgotten."""
        out = self.sequences()
        self._ticks, self._rows, self._values = [], [], []
        return out

    def sequences(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per row: (ticks, values) of its turning points in time order."""
        if not self._rows:
            return [(np.zeros(0, dtype=np.int64), np.zeros(0)) for _ in range(self.n)]
        rows = np.concatenate(self._rows)
        ticks = np.concatenate(self._ticks)
        values = np.concatenate(self._values)
        order = np.lexsort((ticks, rows))
        rows, ticks, values = rows[order], ticks[order], values[order]
        bounds = np.searchsorted(rows, np.arange(self.n + 1))
        return [(ticks[a:b], values[a:b]) for a, b in itertools.pairwise(bounds)]


def damage_sums(ticks: np.ndarray, values: np.ndarray, bin_edges: np.ndarray, m: float = WOHLER_M) -> np.ndarray:
    """Σ n_i S_i^m of the rainflow cycles of one turning-point sequence, per bin of ``bin_edges`` (ticks).

    Each cycle is booked at the tick where it closes (half cycles of the residue at their second point).
    """
    out = np.zeros(len(bin_edges) - 1)
    if len(values) < 2:
        return out
    cycles = np.array([(rng, count, i_end) for rng, _mean, count, _i0, i_end in rainflow.extract_cycles(values)])
    if len(cycles) == 0:
        return out
    book_cycles(out, bin_edges, ticks[cycles[:, 2].astype(int)], cycles[:, 0], cycles[:, 1], m)
    return out


def book_cycles(
    out: np.ndarray, bin_edges: np.ndarray, at: np.ndarray, rng: np.ndarray, count: np.ndarray, m: float
) -> None:
    """Add n S^m of each cycle (range ``rng``, count ``count``) to the bin of ``out`` holding its closing tick ``at``,
    in the cycles' order."""
    which = np.clip(np.searchsorted(bin_edges, at, side="right") - 1, 0, len(out) - 1)
    np.add.at(out, which, count * rng**m)


def del_from_sums(sums: np.ndarray, seconds: float, m: float = WOHLER_M) -> np.ndarray:
    """DEL = (Σ n S^m / T)^{1/m} (N m) at N_eq = 1 Hz, from damage sums over a span of ``seconds``."""
    return (np.asarray(sums) / seconds) ** (1.0 / m)


def imbalance_phasor(blade_torque: np.ndarray) -> np.ndarray:
    """Σ_i τ_r,i e^{j2π(i−1)/3} for blade torques (n, 3) in N m: the rotating-frame 1P imbalance, (n,) complex."""
    return blade_torque @ BLADE_PHASOR
