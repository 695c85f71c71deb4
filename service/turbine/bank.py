"""The bank of seed 000's observers, run together every tick for a batch of turbines.

Observers (seed 000, Section 3; "faulty" is the sensor set each one leaves out):

=====  ==========================  ===================================================
paper  observer instances          sensors used (``y_j``, eqs. (4)–(10))
=====  ==========================  ===================================================
1, 7   ``1``                       ω_r,m1 ω_r,m2 ω_g,m1 ω_g,m2 (7 = 1 here: the anemometer measures no state)
2      ``2-r1``, ``2-r2``          one rotor-speed sensor left out
3      ``3-g1``, ``3-g2``          one generator-speed sensor left out
4      ``4``                       ω_g,m1 ω_g,m2 (no UIO exists: the rigid drive train, ``uio.design_rigid``)
5      ``5``                       ω_r,m1 ω_r,m2
6      ``6-r1g1`` … ``6-r2g2``     one rotor- and one generator-speed sensor left out
–      ``5-pe15`` … ``5-pe-r3``    ω_r,m1 ω_r,m2 and ω_g,pe = P_g,m/(η_gc τ_g,m), four designs (not
                                   isolating; the estimate when both generator-speed sensors are flagged,
                                   ``docs/turbine.md``)
–      ``4-g1``, ``4-g2``          observer 4 on one generator-speed sensor (not isolating: the estimate when
                                   the other is flagged)
=====  ==========================  ===================================================

All observers are computed at each sample (seed 000, after eq. (20)); their states are stacked into one array
and advanced with block matrices, so the whole bank costs a few matrix products per tick.

The non-fault-tolerant estimate of seed 000 ("observer 1 throughout") is a separate copy of observer 1
(``1-nfte``), so that nothing the supervisor does to its own observers can make the comparison kinder.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from service.turbine.design_model import DesignModel
from service.turbine.uio import (
    ObserverDesign,
    design_augmented_kalman,
    design_rigid,
    design_uio,
    existence_problem,
)
from wwcore.channels import SPEED_SENSORS

SHORT = {"omega_r_m1": "r1", "omega_r_m2": "r2", "omega_g_m1": "g1", "omega_g_m2": "g2"}
ROTOR = ("omega_r_m1", "omega_r_m2")
GENERATOR = ("omega_g_m1", "omega_g_m2")
POWER_SPEED = "omega_g_pe"  # the power-speed channel P_g,m / (η_gc τ_g,m), rad/s (``interfaces.power_speed``)


def paper_number(left_out: frozenset[str]) -> int:
    """Seed 000's observer number for a set of left-out (faulty) speed sensors."""
    rotor, gen = len(left_out & set(ROTOR)), len(left_out & set(GENERATOR))
    table = {(0, 0): 1, (1, 0): 2, (0, 1): 3, (2, 0): 4, (0, 2): 5, (1, 1): 6}
    return table[(rotor, gen)]


def observer_name(left_out: frozenset[str]) -> str:
    number = paper_number(left_out)
    suffix = "".join(SHORT[s] for s in SPEED_SENSORS if s in left_out)
    return str(number) if number in (1, 4, 5) else f"{number}-{suffix}"


def bank_subsets() -> list[frozenset[str]]:
    """Left-out sets of the bank: none, any one sensor, or two sensors of the paper's cases 4–6."""
    out = [frozenset()]
    out += [frozenset({s}) for s in SPEED_SENSORS]
    out += [frozenset(pair) for pair in itertools.combinations(SPEED_SENSORS, 2)]
    return out


@dataclass(frozen=True)
class BankDesign:
    """The observers of the bank and their block matrices over the 4 speed sensors."""

    left_out: tuple[frozenset[str], ...]  # of the isolating observers 0 … n_isolating − 1
    names: tuple[str, ...]  # every observer, the NFTE copy of observer 1 last
    observers: tuple[ObserverDesign, ...]
    inputs: tuple[str, ...]  # the bank's input columns: the 4 speed sensors, then POWER_SPEED if it has 5-pe
    offsets: np.ndarray  # start column of each observer's state block
    F_blk: np.ndarray  # steady-state block-diagonal F
    K_blk: np.ndarray  # (Σn, n_inputs): K_j M_j stacked
    H_blk: np.ndarray  # (Σn, n_inputs): H_j M_j stacked
    TB_blk: np.ndarray  # (Σn,)
    F_transient: np.ndarray  # (N, Σn, Σn)
    K_transient: np.ndarray  # (N, Σn, n_inputs)
    G_res: np.ndarray  # (Σrank, n_inputs): W_j (I − C_j H_j) M_j stacked
    L_res: np.ndarray  # (Σrank, Σn): block-diag W_j C_j
    res_starts: np.ndarray  # start row of each observer's whitened residual
    ranks: np.ndarray  # (n_obs,)
    reference: int  # index of the NFTE copy of observer 1
    power_speed: tuple[int, ...]  # indices of the 5-pe observers (rotor-speed sensors and the power-speed channel)
    # indices of observer 4 on one generator-speed sensor: the one that leaves out GENERATOR[i] is
    # single_generator[i] (not isolating: they serve the estimate only, ``builtin``)
    single_generator: tuple[int, ...] = ()
    gear_ratio: float = 1.0  # N_g, generator over rotor speed

    @property
    def n_isolating(self) -> int:
        return len(self.left_out)

    def index(self, left_out: frozenset[str]) -> int:
        return self.left_out.index(left_out)


def _selector(sensors: tuple[str, ...], inputs: tuple[str, ...]) -> np.ndarray:
    M = np.zeros((len(sensors), len(inputs)))
    for row, name in enumerate(sensors):
        M[row, inputs.index(name)] = 1.0
    return M


def design_bank(
    model: DesignModel,
    sigma: dict[str, float],
    Q: np.ndarray,
    q_unknown: float,
    power_speed: Sequence[tuple[str, float, float | None]] = (),
    single_generator: bool = False,
) -> BankDesign:
    """Design every observer of the bank. ``sigma``: noise σ of each speed sensor (its own units);
    ``power_speed``: (name, σ of the power-speed channel in rad/s, random-walk variance of the aerodynamic
    torque per tick, or None for the rigid form) of each 5-pe observer to add; with
    ``single_generator``, observer 4 (rigid) on one generator-speed sensor, ``4-g1`` (on ω_g,m2) and ``4-g2`` (on
    ω_g,m1), observer 4 with one more sensor left out. Neither kind is isolating: they serve the estimate only."""
    left_outs = bank_subsets()
    inputs = (*SPEED_SENSORS, POWER_SPEED) if power_speed else SPEED_SENSORS

    gear_ratio = -1.0 / model.A[2, 1]  # dθ_Δ/dt = ω_r − ω_g/N_g

    def seed_observer(sensors: tuple[str, ...]) -> ObserverDesign:
        """The UIO of eqs. (11)–(20); where it does not exist, the rigid drive train on the generator-speed
        sensors (observer 4) or the augmented Kalman filter (observer 5)."""
        R = np.diag([sigma[s] ** 2 for s in sensors])
        problem = existence_problem(model, sensors)
        if problem is None:
            return design_uio(model, sensors, R, Q)
        if set(sensors) <= set(GENERATOR):
            return design_rigid(model, sensors, R, gear_ratio, note=f"rigid drive train; no UIO: {problem}")
        return design_augmented_kalman(model, sensors, R, Q, q_unknown, note=problem)

    observers = [seed_observer(tuple(s for s in SPEED_SENSORS if s not in left_out)) for left_out in left_outs]
    # 5-pe: a UIO exists here but decouples τ_r through the noisy rotor-speed sensors; the Kalman form weighs all
    # three channels by their noise (wind RMSE 0.21 against the UIO's 0.37 m/s, docs/turbine.md).
    note = "Kalman form by choice: rotor-speed sensors plus the power-speed channel"
    for _, pe_sigma, pe_q in power_speed:
        R = np.diag([sigma[s] ** 2 for s in ROTOR] + [pe_sigma**2])
        if pe_q is None:
            observers.append(design_rigid(model, (*ROTOR, POWER_SPEED), R, gear_ratio, note="5-pe, rigid form"))
        else:
            observers.append(design_augmented_kalman(model, (*ROTOR, POWER_SPEED), R, Q, pe_q, note=note))
    one_generator = [tuple(g for g in GENERATOR if g != left) for left in GENERATOR] if single_generator else []
    for sensors in one_generator:  # observer 4 on the one generator-speed sensor left
        observers.append(seed_observer(sensors))
    observers.append(seed_observer(SPEED_SENSORS))  # the NFTE copy of observer 1, last
    sizes = [o.n_states for o in observers]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    selectors = [_selector(o.sensors, inputs) for o in observers]
    n_transient = max(len(o.F_transient) for o in observers)

    reference = len(observers) - 1

    def gains_at(step: int) -> tuple[np.ndarray, np.ndarray]:
        Fs, Ks = [], []
        for o, M in zip(observers, selectors, strict=True):
            if step < len(o.F_transient):
                Fs.append(o.F_transient[step])
                Ks.append(o.K_transient[step] @ M)
            else:
                Fs.append(o.F)
                Ks.append(o.K @ M)
        return block_diag(*Fs), np.vstack(Ks)

    transient = [gains_at(step) for step in range(n_transient)]
    F_blk, K_blk = gains_at(10**9)
    G_res = np.vstack(
        [o.whitening @ (np.eye(len(o.sensors)) - o.C @ o.H) @ M for o, M in zip(observers, selectors, strict=True)]
    )
    L_res = block_diag(*[o.whitening @ o.C for o in observers])
    ranks = np.array([o.rank for o in observers])
    return BankDesign(
        left_out=tuple(left_outs),
        names=(
            *(observer_name(s) for s in left_outs),
            *(name for name, _, _ in power_speed),
            *(f"4-{SHORT[g]}" for g in GENERATOR[: len(one_generator)]),
            "1-nfte",
        ),
        observers=tuple(observers),
        inputs=inputs,
        offsets=offsets,
        F_blk=F_blk,
        K_blk=K_blk,
        H_blk=np.vstack([o.H @ M for o, M in zip(observers, selectors, strict=True)]),
        TB_blk=np.concatenate([o.TB.ravel() for o in observers]),
        F_transient=np.array([f for f, _ in transient]),
        K_transient=np.array([k for _, k in transient]),
        G_res=G_res,
        L_res=L_res,
        res_starts=np.concatenate([[0], np.cumsum(ranks)[:-1]]),
        ranks=ranks,
        reference=reference,
        power_speed=tuple(range(len(left_outs), len(left_outs) + len(power_speed))),
        single_generator=tuple(range(len(left_outs) + len(power_speed), reference)),
        gear_ratio=float(gear_ratio),
    )


def estimate_observers(design: BankDesign, from_generator: bool = True, power_speed: bool = True) -> np.ndarray:
    """The observer the estimate comes from, for each bitmask of flagged speed sensors (16,), −1 where none.

    ``from_generator``: observer 4, the rigid drive train on the healthy generator-speed sensors (4 with both, 4-g1 or
    4-g2 with one), whatever the rotor-speed sensors' flags, so no rotor-speed reading ever reaches the estimate
    while a generator-speed sensor is healthy; otherwise (seed 000) the observer of the healthy set. With both
    generator-speed sensors flagged: the first 5-pe design if ``power_speed`` and the bank has it (the caller
    picks the observer of the torque band, ``power_speed_estimate_observers``), else observer 5.
    """
    choice = np.full(1 << len(SPEED_SENSORS), -1)
    bit = {s: 1 << SPEED_SENSORS.index(s) for s in SPEED_SENSORS}
    for j, left_out in enumerate(design.left_out):
        choice[sum(bit[s] for s in left_out)] = j
    both_generator = bit[GENERATOR[0]] | bit[GENERATOR[1]]
    if power_speed and design.power_speed:
        choice[both_generator] = design.power_speed[0]
    if not from_generator:
        return choice
    if len(design.single_generator) != len(GENERATOR):
        raise ValueError("the bank has no observer 4 on one generator-speed sensor (design_bank single_generator)")
    both_rotor = design.index(frozenset(ROTOR))
    for mask in range(len(choice)):
        flagged = [g for g in GENERATOR if mask & bit[g]]
        if not flagged:
            choice[mask] = both_rotor
        elif len(flagged) == 1:
            choice[mask] = design.single_generator[GENERATOR.index(flagged[0])]
    return choice


def power_speed_estimate_observers(design: BankDesign, power_speed: bool = True) -> np.ndarray:
    """The observer the estimate comes from with both generator-speed sensors distrusted, for each torque band of
    ``interfaces.power_speed_band`` (empty without ``power_speed`` or 5-pe designs: observer 5 serves every band,
    ``estimate_observers``): 5-pe15, 5-pe35, 5-pe80 (region 2, the design nearest the torque), 5-pe-r3 (region 3),
    and observer 5 in region 1, below the power-speed channel's threshold, where that channel is N_g × the
    rotor-speed sensors' mean: 5-pe holds nothing observer 5 lacks there, and observer 5's wind filter is the one
    consistent with the rotor-speed sensors' noise (``wind_recovery.torque_cutoffs``; decision N-15)."""
    if not (power_speed and design.power_speed):
        return np.zeros(0, dtype=np.int64)
    return np.array([*design.power_speed, design.index(frozenset(GENERATOR))], dtype=np.int64)


SPARSE_PRODUCT_ROWS = 16
"""Banks of at least this many rows make their two products over the matrices' nonzeros on the compiled backend
(``ObserverBank._sparse_products``), fewer by BLAS (the same numbers): the sparse products' fixed cost per column
makes them the slower below 8–16 rows (CPU time of a bank step: 2 rows 8.9 µs against BLAS's 5.3, 8 rows 9.6 against
9.4, 16 rows 12.2 against 14.9, 50 rows 27.1 against 36.1)."""


class ObserverBank:
    """Runs a ``BankDesign`` for n turbines: eqs. (11)–(12) for every observer, plus whitened residuals.

    Each tick is two matrix products: [z, u, y_prev] @ [Fᵀ; (TB)ᵀ; Kᵀ] gives z[n] (11), and
    [z[n], y[n]] @ [[I, −Lᵀ], [Hᵀ, Gᵀ]] gives x̂[n] (12) and the whitened residuals side by side.
    """

    def __init__(self, design: BankDesign, n: int, fast=None):
        self.d = design
        self._fast = fast  # ``service.turbine.fast`` (``wwcore.backend``) or None
        self.n = n
        width = design.F_blk.shape[0]

        def update_matrix(F: np.ndarray, K: np.ndarray) -> np.ndarray:
            # C order: stacked from transposes it would come out in Fortran order, which BLAS multiplies ~1.5×
            # slower at these sizes (50 × 71 by 71 × 65)
            return np.ascontiguousarray(np.vstack([F.T, design.TB_blk[None, :], K.T]))

        self._update = update_matrix(design.F_blk, design.K_blk)
        self._update_transient = [
            update_matrix(F, K) for F, K in zip(design.F_transient, design.K_transient, strict=True)
        ]
        self._output = np.block([[np.eye(width), -design.L_res.T], [design.H_blk.T, design.G_res.T]])
        self._width = width
        if fast is not None:
            self._sparse = self._sparse_products(fast, n)
        # The left operands of the two products, [z, u, y_prev] and [z, y], refilled in place every tick
        # (cheaper than concatenating; the same C-contiguous arrays, so the same products).
        self._update_in = np.empty((n, width + 1 + design.K_blk.shape[1]))
        self._output_in = np.empty((n, width + design.H_blk.shape[1]))
        # χ²_j sums rank_j (1–3) squared residuals. ``np.add.reduceat`` adds a segment as w_0 + (w_1 + w_2) but
        # costs a C call per row and observer; three gathers of the segments' first, second and third element (a
        # zero column where the segment is shorter) add them in that order, for one call each.
        if design.ranks.max() > 3:
            raise ValueError("the χ² gather assumes whitened residuals of rank ≤ 3")
        n_res = int(design.ranks.sum())
        self._squares = np.zeros((n, n_res + 1))  # w², the last column stays 0
        self._terms = np.concatenate(
            [np.where(design.ranks > i, design.res_starts + i, n_res) for i in range(3)]
        )  # (3 n_obs,) columns of _squares: first, second, third element of each segment
        self._work = (self._update_in, self._output_in, self._terms, n_res)  # the compiled steps' work arrays
        self.z = np.zeros((n, width))
        self.x_hat = np.zeros((n, width))
        self.chi2 = np.zeros((n, len(design.names)))  # ‖W_j r_j‖², χ²-distributed with rank_j dof when healthy
        self.steps = 0
        self._y_prev: np.ndarray | None = None  # y[n−1]
        # ``step_readings``' arguments kept once the transient update matrices are used up: the inputs' constants,
        # the steady update, the output, the work arrays and the nonzeros, as one ``wwcore.kept.Kept``
        self.kept = None

    def initialise(self, x0: np.ndarray, y: np.ndarray) -> None:
        """Start every observer at the state estimate x0 (n, 4): z[0] = x0 − H y[0] (and d̂ from x0 statics)."""
        d = self.d
        for j, o in enumerate(d.observers):
            block = slice(d.offsets[j], d.offsets[j] + o.n_states)
            target = x0 if o.n_states == 4 else np.column_stack([x0, np.zeros(self.n)])
            self.z[:, block] = target
        self.z -= y @ d.H_blk.T
        self.x_hat = self.z + y @ d.H_blk.T

    def step(self, y: np.ndarray, u_prev: np.ndarray) -> None:
        """Advance with y[n] (n, n_inputs: the speed sensors, then the power-speed channel if any) and u[n−1]
        (n,) the torque reference of the previous tick."""
        width = self._width
        if self._fast is not None:
            self._fast_step(y, u_prev)
            return
        if self._y_prev is not None:
            update = self._update_transient[self.steps] if self.steps < len(self._update_transient) else self._update
            # (11) z[n] = F z[n−1] + T B_d u[n−1] + K y[n−1]
            stacked = self._update_in
            stacked[:, :width] = self.z
            stacked[:, width] = u_prev
            stacked[:, width + 1 :] = self._y_prev
            self.z = stacked @ update
            self.steps += 1
        # (12) x̂[n] = z[n] + H y[n], and r_j = (I − C_j H_j) y_j − C_j z_j whitened by W_j: χ²_j = ‖W_j r_j‖²
        stacked = self._output_in
        stacked[:, :width] = self.z
        stacked[:, width:] = y
        out = stacked @ self._output
        self.x_hat = out[:, :width]
        white = out[:, width:]
        squares = self._squares
        np.multiply(white, white, out=squares[:, :-1])
        terms = squares[:, self._terms]
        m = len(self.d.ranks)
        self.chi2 = terms[:, :m] + (terms[:, m : 2 * m] + terms[:, 2 * m :])  # = reduceat(w², res_starts)
        self._y_prev = y

    def _sparse_products(self, fast, n: int) -> tuple:
        """The two products' matrices as their nonzeros for ``fast.gemm_product`` (the update's and its transient
        versions', the output's), for ``SPARSE_PRODUCT_ROWS`` rows or more where ``fast.gemm_layout`` finds BLAS's
        arithmetic for these shapes and n rows; else BLAS products (fewer rows; another BLAS or CPU). The matrices
        are sparse (4–8 % nonzero): the products over their nonzeros are a twentieth of BLAS's dense work, with the
        same numbers."""
        (k_update, n_update), (k_output, n_output) = self._update.shape, self._output.shape
        update_lanes = output_lanes = None
        if n >= SPARSE_PRODUCT_ROWS:
            update_lanes = fast.gemm_layout(n, k_update, n_update)
            output_lanes = fast.gemm_layout(n, k_output, n_output)
        reproduced = update_lanes is not None and output_lanes is not None
        if not reproduced:
            update_lanes = output_lanes = 0
        self._update_nonzeros = fast.nonzeros(self._update, update_lanes)
        self._transient_nonzeros = [fast.nonzeros(m, update_lanes) for m in self._update_transient]
        return reproduced, fast.nonzeros(self._output, output_lanes)

    def _fast_products(self, advance: bool) -> tuple:
        """The update matrix of this step (a transient one over the first steps) and ``fast.bank_step``'s
        ``sparse`` = (reproduced, its nonzeros, the output's nonzeros) (``_sparse_products``)."""
        reproduced, output_nonzeros = self._sparse
        update, update_nonzeros = self._update, self._update_nonzeros
        if advance and self.steps < len(self._update_transient):
            update, update_nonzeros = self._update_transient[self.steps], self._transient_nonzeros[self.steps]
        return update, (reproduced, update_nonzeros, output_nonzeros)

    def _fast_step(self, y: np.ndarray, u_prev: np.ndarray) -> None:
        """``step`` by one kernel (``service.turbine.fast.bank_step``: the stacking, the two products as numpy's,
        over the matrices' nonzeros or by BLAS, the χ² sums)."""
        advance = self._y_prev is not None
        update, sparse = self._fast_products(advance)
        update_in, output_in, terms, n_res = self._work
        self.chi2 = np.empty((self.n, len(self.d.names)))
        self.z, out = self._fast.bank_step(
            self.z, u_prev, self._y_prev if advance else y, update, update_in, y, self._output, output_in, terms,
            n_res, advance, self.chi2, sparse,
        )  # fmt: skip
        self.steps += advance
        self.x_hat = out[:, : self._width]
        self._y_prev = y

    def step_readings(self, inputs: tuple, offset: np.ndarray | None, u_prev: np.ndarray) -> tuple:
        """``step`` with y[n] gathered from a frame's readings by the same kernel call (``fast.bank_tick``: the
        inputs as ``TurbineContext._bank_inputs``'s, ``inputs`` = (sensors, columns, threshold, N_g, η_gc), less
        the speed sensors' calibration ``offset`` (n, 4) if any); after the first step, with the compiled backend
        only. ``inputs[1:]`` are constants: once the transient update matrices are used up, they are kept with the
        bank's other kept arguments (``fast.bank_tick_kept``). The speed readings before the offset (n, 4)."""
        n = self.n
        read = np.empty((n, 6))
        speed = np.empty((n, 4)) if offset is not None else read[:, :4]
        chi2 = np.empty((n, len(self.d.names)))
        subtract, offset = offset is not None, speed if offset is None else offset
        if self.steps < len(self._update_transient):
            update, sparse = self._fast_products(True)
            z, out = self._fast.bank_tick(
                inputs, subtract, offset, speed, read, self.z, u_prev, self._y_prev, update, self._output, self._work,
                chi2, sparse,
            )  # fmt: skip
        else:  # the steady update: the kept arguments as one struct (``fast.bank_tick_kept``)
            if self.kept is None:
                update, sparse = self._fast_products(True)
                self.kept = self._fast.Kept((*inputs[1:], update, self._output, self._work, sparse))
            z, out = self._fast.bank_tick_kept(
                inputs[0], subtract, offset, speed, read, self.z, u_prev, self._y_prev, chi2, self.kept
            )
        self.ticked(z, out, read, chi2)
        return speed

    def ticked(self, z: np.ndarray, out: np.ndarray, read: np.ndarray, chi2: np.ndarray) -> None:
        """``step_readings``' bookkeeping after its kernel (z, out; the inputs ``read`` and χ² ``chi2`` it wrote),
        also where a caller's kernel made the same call (``fast_supervisor``): x̂ from ``out``, y[n] (``read``'s
        first 5 columns) kept for the next step."""
        self.z, self.chi2 = z, chi2
        self.steps += 1
        self.x_hat = out[:, : self._width]
        self._y_prev = read[:, :5]

    def restart(self, rows: np.ndarray, target: np.ndarray, source: np.ndarray) -> None:
        """Re-initialise observer ``target[i]`` of row ``rows[i]`` from observer ``source[i]``'s estimate of this
        tick: x̂_target = x̂_source, z_target = x̂_source − H_target y[n] (eq. (12)), so it goes on from a state
        that never saw what the source left out. Only between observers of one kind (a UIO from a UIO, a Kalman
        filter from a Kalman filter); a rigid drive train has no history to restart (its x̂ is the tick's
        readings)."""
        d = self.d
        y = self._y_prev  # y[n], the readings of the last step
        for row, t, s in zip(rows, target, source, strict=True):
            kind = d.observers[t].kind
            if kind == "rigid" or kind != d.observers[s].kind:
                continue  # a rigid x̂ is this tick's readings; other kinds estimate different things (θ̂_Δ, τ̂_r)
            tb = slice(d.offsets[t], d.offsets[t] + d.observers[t].n_states)
            sb = slice(d.offsets[s], d.offsets[s] + d.observers[s].n_states)
            self.x_hat[row, tb] = self.x_hat[row, sb]
            self.z[row, tb] = self.x_hat[row, sb] - d.H_blk[tb] @ y[row]

    def states(self, j: int) -> np.ndarray:
        """x̂ of observer j, (n, n_states_j)."""
        o = self.d.observers[j]
        return self.x_hat[:, self.d.offsets[j] : self.d.offsets[j] + o.n_states]
