r"""The farm fault detector of seed 001 (Borchersen, Larsen & Stoustrup), as published: detector ``paper``.

1. **Wind direction and rows.** The paper compares each turbine with the others of its *row*: the turbines at the
   same distance along the wind. Its rows come from the direction and the layout (``FarmContext.rows``: turbines
   within ``ROW_TOLERANCE_D`` = 0.5 D of each other along the wind, each row anchored at its most upwind turbine).
   The direction comes, per farm, from (option ``direction_source``)

   * ``power``, eqs. (1)–(2), seed 001's 3 × 3 only: the first 500 farm samples, p = |mean(P_1 − P_4)|; case 1
     (270°) if p ≤ 10 kW, else case 2 (315°). Nothing is tested before the case is known. With option
     ``running_case`` (default ``RUNNING_CASE``) the estimate runs: eq. (1) is taken again on every following block
     of 500 samples (50 s), and the case changes when two consecutive blocks both give the other case, blocks
     during which a fault was reported not counting (a faulty turbine 1 or 4 biases P_1 − P_4: debris alone is
     3 % of its power). The test knows these two directions only: on the 3 × 3 in another wind it picks the nearer
     pattern, so a farm whose wind leaves the two cases needs ``vane``;
   * ``vane``: the met mast's wind vane, a running circular mean of its readings (the mean of all so far, then
     first order with ``direction_averaging_s``, default 60 s: σ ≈ 0.2° with the vane's 5°, and a lag of
     ``direction_averaging_s`` × the veer rate behind a steadily moving wind, 1.8° at 0.03°/s). Nothing is tested
     before 500 samples (as eq. (1) waits); the rows are formed again whenever the estimate has moved more than
     ``regroup_deg`` (default 1°, several times the estimate's noise: a layout's rows can change within a degree,
     Horns Rev 1's at 270.7°) from the direction they were formed for, the CUSUMs keeping their state (a
     turbine's comparison changes, not its test) and each row's eq. (3) delay following its new distance;
   * ``auto`` (the default): ``power`` on seed 001's 3 × 3, ``vane`` on any other layout.

   Options ``wind_case`` (1 or 2, the 3 × 3 only) and ``wind_direction_deg`` give the direction instead: diagnostics,
   not the paper's method.
2. **Row winds** (eq. (3)): the mast reading delayed by d_j/v̄, v̄ = v_mast/(s + 1).
3. **Fault 1, debris** (eqs. (4)–(7), Table 1): P_e = f_ω⁻¹(ω_m) (``power_curve.power_from_speed``),
   r = P_m − P_e, CUSUM with μ_0 = 0, μ_1 = −Amp P_e, Amp = 0.027, σ² = 3000. *Decision D-7*: the paper writes
   μ_1 = +0.027 P_e, but debris *lowers* P_m, so r falls by 3 %; the test is run for the drop the paper means.
4. **Fault 2, pitch** (eqs. (8)–(10), Table 2): per blade, r = β_t,i − β_comp,t with β_t,i the blade's measured
   pitch (mean of its two encoders) and β_comp,t the mean measured pitch (all blades) of the other turbines in
   the row; no test for a turbine alone in its row. μ_1 = 0.2, σ² = 0.05. *Decision D-8*: "the pitch
   measurement β_t" is read per blade, since a misalignment sits on one blade.
5. **Fault 3, drive train** (eqs. (11)–(16), Table 3): ω_t is the 3P content of the generator speed (lock-in
   amplitude, ``signals.LockIn3P``, τ = 1.5 s) — *Decision D-14*: a signed band-passed residual has zero mean,
   so the CUSUM's mean shift μ_1 = 0.1 rad/s can only be a shift of the 3P *amplitude*. ω_comp is the mean
   amplitude of the row's other turbines, or for a lone turbine the 3P amplitude of eq. (11)'s
   ω_gest = f_ω(P_cest)(1 + γ_ω/ω_g,max sin(σ_p 2π t)), i.e. f_ω(P_cest) γ_ω/ω_g,max, with P_cest from eqs.
   (12)–(13) (P_ag = P_a(v_est) through τ_w/(s + α_w), α_w = τ_w = v_est/D). γ_ω/ω_g,max = ``KAPPA_3P`` is not
   given in the paper; we take the mean 3P amplitude per unit generator speed of fault-free runs (docs/farm.md).
   μ_1 = 0.1, σ² = 0.3.
6. **Decision** (eq. (17), Table 4) per fault and turbine (``cusum.PaperCusum``), and **one fault at a time**
   (Section 3.7): per farm, the first flag to rise is reported until it falls; flags rising meanwhile are not
   reported. Ties within one sample go to the lowest fault number, then the lowest turbine number.
"""

from __future__ import annotations

import math

import numpy as np

from service.farm.cusum import PaperCusum, llr_increment
from service.farm.interfaces import BETA, N_TYPES, OMEGA_G, P_G, FarmContext, FarmDiagnosis, FarmSample
from service.farm.power_curve import available_power, power_from_speed, speed_from_power
from service.farm.signals import LockIn3P, MastDelays
from service.plugins import AlgorithmOptionError
from wwcore.layout import SEED001_DIRECTIONS_DEG
from wwcore.scenario.farm import FARM_DT_S, ROTOR_DIAMETER_M

CASE_SAMPLES = 500  # eq. (1)
CASE_THRESHOLD_W = 10e3  # eq. (2)
AMP_F1 = 0.027  # Table 1
SIGMA2_F1 = 3000.0  # Table 1
MU1_F2, SIGMA2_F2 = 0.2, 0.05  # Table 2
MU1_F3, SIGMA2_F3 = 0.1, 0.3  # Table 3
H1 = (0.25e6, 60.0, 3.0)  # Table 4, h_1 of faults 1–3
H0 = (0.1e6, 0.1, 0.5)  # Table 4, h_0 of faults 1–3
LOCKIN_TAU_S = 1.5  # s, low-pass of the 3P lock-in [PROPOSED]
KAPPA_3P = 5.0e-3  # –, γ_ω/ω_g,max of eq. (11): mean fault-free 3P amplitude / ω_g (docs/farm.md) [PROPOSED]
DIRECTION_AVERAGING_S = 60.0  # s, time constant of the vane's running circular mean [PROPOSED]
REGROUP_DEG = 1.0  # deg the direction estimate moves before the rows are formed again [PROPOSED]
RUNNING_CASE = True  # eqs. (1)–(2) taken again on every block of CASE_SAMPLES (module docstring) [PROPOSED]
DIRECTION_SOURCES = ("auto", "power", "vane")  # option direction_source (module docstring)


def row_matrices(rows: list[tuple[int, ...]], turbines: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(M, alone): M[t, u] = 1/(|row| − 1) for the other turbines u of t's row, alone[t] when t has none; for
    ``turbines`` turbines (default: the highest number in ``rows``)."""
    turbines = turbines or max(max(row) for row in rows)
    m = np.zeros((turbines, turbines))
    alone = np.zeros(turbines, dtype=bool)
    for row in rows:
        for t in row:
            others = [u for u in row if u != t]
            alone[t - 1] = not others
            for u in others:
                m[t - 1, u - 1] = 1.0 / len(others)
    return m, alone


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a − b| in degrees on the circle (0 … 180)."""
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


class PaperDetector:
    """Seed 001's detector, vectorised over farms of N turbines (module docstring)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.context = context
        self.p = context.params
        n, farms, per_farm = context.n, context.farms, context.turbines
        self.n, self.farms, self.per_farm = n, farms, per_farm
        case = options.get("wind_case")
        direction = options.get("wind_direction_deg")
        if case is not None and not context.paper_grid:
            raise AlgorithmOptionError(
                "wind_case: the paper's wind cases 1 and 2 are directions on seed 001's 3 × 3; this farm has "
                f"{per_farm} turbines elsewhere (give wind_direction_deg, or let the mast's vane give it)"
            )
        if case is not None and direction is not None:
            raise AlgorithmOptionError("wind_direction_deg: give the wind case or the direction, not both")
        if case is not None:
            direction = SEED001_DIRECTIONS_DEG[int(case)]
        source = str(options.get("direction_source", "auto"))
        if source not in DIRECTION_SOURCES:
            raise AlgorithmOptionError(f"direction_source: {source!r} is not one of {', '.join(DIRECTION_SOURCES)}")
        if source == "power" and not context.paper_grid:
            raise AlgorithmOptionError(
                "direction_source: 'power' is the paper's eqs. (1)–(2), written for seed 001's 3 × 3; this farm "
                f"has {per_farm} turbines elsewhere (use 'vane' or 'auto')"
            )
        self.given = direction is not None
        self.from_power = not self.given and source != "vane" and context.paper_grid  # eqs. (1)–(2)
        self.case = np.full(farms, int(case) if case is not None else 0)  # 3 × 3: 0 not yet estimated
        self._p14 = np.zeros(farms)  # Σ (P_1 − P_4) over the current block of 500 samples
        self._running_case = bool(options.get("running_case", RUNNING_CASE))
        self._block_quiet = np.ones(farms, dtype=bool)  # no fault reported during the current block
        self._pending = np.zeros(farms, dtype=int)  # the case the last quiet block gave (0: none)
        self._samples = 0
        self._tau = float(options.get("direction_averaging_s", DIRECTION_AVERAGING_S))
        self._regroup = float(options.get("regroup_deg", REGROUP_DEG))
        self._vane = np.zeros((farms, 2))  # running mean of (cos, sin) of the vane's readings
        self.direction = np.full(farms, np.nan if direction is None else float(direction))  # deg, the estimate
        self.grouped = np.full(farms, np.nan)  # deg, the direction each farm's rows were formed for
        self.rows: list[list[tuple[int, ...]]] = [[] for _ in range(farms)]
        self._m = np.zeros((farms, per_farm, per_farm))  # row_matrices per farm
        self._alone = np.zeros((farms, per_farm), dtype=bool)
        self._distances = np.zeros((farms, per_farm))  # m, mast to each turbine's row along the wind
        self.mast = MastDelays(farms)
        self.lockin = LockIn3P(n, LOCKIN_TAU_S)
        self.p_ag: np.ndarray | None = None  # eq. (12) state
        self.cusum = [
            PaperCusum((n,), H1[0], H0[0]),
            PaperCusum((n, 3), H1[1], H0[1]),
            PaperCusum((n,), H1[2], H0[2]),
        ]
        self.reported = np.full(farms, -1)  # per farm: index type·N + (t − 1) of the reported fault, −1 none
        self.residuals = np.zeros((n, N_TYPES))

    # -- the direction and the rows --------------------------------------------------------------------------
    def _estimate_direction(self, sample: FarmSample, power: np.ndarray) -> None:
        """Eqs. (1)–(2) on the 3 × 3, the vane's running mean elsewhere; ``direction`` stays NaN until known."""
        if self.given:
            return
        if self.from_power:
            first = self.case == 0
            if first.any() or self._running_case:
                per = power.reshape(self.farms, self.per_farm)
                self._p14 += per[:, 0] - per[:, 3]
                self._block_quiet &= self.reported < 0  # a block with a fault reported does not count
                if (self._samples + 1) % CASE_SAMPLES == 0:
                    p_wm = np.abs(self._p14 / CASE_SAMPLES)
                    block = np.where(p_wm <= CASE_THRESHOLD_W, 1, 2)  # eq. (2) on this block
                    confirmed = self._block_quiet & (block == self._pending)  # two quiet blocks in a row agree
                    self.case = np.where(first | confirmed, block, self.case)
                    self._pending = np.where(self._block_quiet, block, 0)
                    self._p14[:] = 0.0
                    self._block_quiet[:] = True
                    self.direction = np.where(self.case == 1, SEED001_DIRECTIONS_DEG[1], SEED001_DIRECTIONS_DEG[2])
            return
        if sample.mast_direction is None:
            raise ValueError(
                "the paper detector on a farm other than seed 001's 3 × 3 needs the mast's wind vane "
                "(mast_direction) or the option wind_direction_deg"
            )
        theta = np.radians(sample.mast_direction)
        unit = np.column_stack([np.cos(theta), np.sin(theta)])
        # the mean of every reading so far until the first-order filter averages over more (k + 1 > τ/Δt): an
        # exponential filter started from one reading would still carry its noise when the rows are first formed
        gain = max(1.0 / (self._samples + 1), 1.0 - math.exp(-FARM_DT_S / self._tau))
        self._vane += (unit - self._vane) * gain
        if self._samples + 1 >= CASE_SAMPLES:
            self.direction = np.mod(np.degrees(np.arctan2(self._vane[:, 1], self._vane[:, 0])), 360.0)

    def _group(self) -> None:
        """Form the rows of every farm whose direction estimate moved ``regroup_deg`` from its rows' (or has none)."""
        known = ~np.isnan(self.direction)
        stale = known & (np.isnan(self.grouped) | (angle_between(self.direction, self.grouped) > self._regroup))
        for f in np.flatnonzero(stale):
            direction = float(self.direction[f])
            rows = self.context.rows(direction)
            m, alone = row_matrices(rows, self.per_farm)
            row_of = np.zeros(self.per_farm, dtype=int)
            for i, row in enumerate(rows):
                row_of[[t - 1 for t in row]] = i
            distances = self.context.mast_distance_m + np.array(self.context.row_distances_m(direction))
            self._m[f], self._alone[f], self._distances[f] = m, alone, distances[row_of]
            self.rows[f], self.grouped[f] = rows, direction

    def step(self, sample: FarmSample) -> FarmDiagnosis:
        p, n, farms, per_farm = self.p, self.n, self.farms, self.per_farm
        y = sample.scada
        self.mast.step(sample.mast)
        power = y[:, P_G]
        omega_g = y[:, OMEGA_G].mean(axis=1)
        amplitude = self.lockin.step(omega_g, omega_g / p.N_g)
        self._estimate_direction(sample, power)
        self._samples += 1
        diagnosis = FarmDiagnosis(
            np.zeros((n, N_TYPES), dtype=bool), np.zeros((n, N_TYPES)), np.tile(np.array(H1), (n, 1))
        )
        if np.isnan(self.direction).any():
            return diagnosis
        self._group()
        alone_t = self._alone.reshape(-1)  # (n,)

        def row_mean_others(x: np.ndarray) -> np.ndarray:  # (n,) → (n,) mean over the row's other turbines
            xf = x.reshape(farms, per_farm)
            return np.matmul(self._m, xf[:, :, None])[:, :, 0].reshape(-1)

        # fault 1, eqs. (4)–(7)
        p_e = power_from_speed(p, omega_g, sample.zone)
        r1 = power - p_e
        f1 = self.cusum[0].step(llr_increment(r1, 0.0, -AMP_F1 * p_e, SIGMA2_F1))
        # fault 2, eqs. (8)–(10): per blade against the row's other turbines' collective pitch
        blades = y[:, BETA].mean(axis=2)  # (n, 3)
        comp = row_mean_others(blades.mean(axis=1))
        r2 = blades - comp[:, None]
        f2 = self.cusum[1].step(llr_increment(r2, 0.0, MU1_F2, SIGMA2_F2), active=~alone_t[:, None])
        # fault 3, eqs. (11)–(16)
        v_est = self.mast.delayed(self._distances).reshape(-1)  # (n,) the wind at each turbine's row, eq. (3)
        p_a = available_power(p, v_est)
        if self.p_ag is None:
            self.p_ag = p_a.copy()
        alpha = np.maximum(v_est, 1.0) / ROTOR_DIAMETER_M  # α_w = τ_w = v/D  [PROPOSED]
        a = np.exp(-alpha * FARM_DT_S)
        self.p_ag = a * self.p_ag + (1.0 - a) * p_a  # eq. (12), exact zoh of τ_w/(s + α_w)
        p_cest = self.p_ag - np.maximum(self.p_ag - sample.power_ref_used, 0.0)  # eq. (13)
        model = KAPPA_3P * speed_from_power(p, p_cest)  # 3P amplitude of eq. (11)
        w_comp = np.where(alone_t, model, row_mean_others(amplitude))
        r3 = amplitude - w_comp  # eq. (14)
        f3 = self.cusum[2].step(llr_increment(r3, 0.0, MU1_F3, SIGMA2_F3))
        flags = np.column_stack([f1, f2.any(axis=1), f3])  # (n, 3)
        self.residuals = np.column_stack([r1, np.abs(r2).max(axis=1), r3])
        diagnosis.statistics = np.column_stack([self.cusum[0].g, self.cusum[1].g.max(axis=1), self.cusum[2].g])
        diagnosis.faulty = self._one_at_a_time(flags)
        diagnosis.extra = {
            "wind_direction": np.repeat(self.direction, per_farm),
            "wind_case": np.repeat(self.case, per_farm),
            "amplitude_3p": amplitude,
        }
        return diagnosis

    def _one_at_a_time(self, flags: np.ndarray) -> np.ndarray:
        """Section 3.7: per farm, report the first flag to rise until it falls."""
        farms, per_farm = self.farms, self.per_farm
        per = flags.reshape(farms, per_farm, N_TYPES).transpose(0, 2, 1).reshape(farms, -1)  # (farms, type·N + t)
        still = (self.reported >= 0) & per[np.arange(farms), np.maximum(self.reported, 0)]
        first = np.where(per.any(axis=1), per.argmax(axis=1), -1)
        self.reported = np.where(still, self.reported, first)
        out = np.zeros((farms, N_TYPES * per_farm), dtype=bool)
        has = self.reported >= 0
        out[np.flatnonzero(has), self.reported[has]] = True
        return out.reshape(farms, N_TYPES, per_farm).transpose(0, 2, 1).reshape(-1, N_TYPES)
