r"""The farm fault detector of seed 001 (Borchersen, Larsen & Stoustrup), as published: detector ``paper``.

1. **Wind direction** (eqs. (1)–(2)): from the first 500 farm samples, p = |mean(P_1 − P_4)|; case 1 if
   p ≤ 10 kW, else case 2. Nothing is tested before the case is known. (Option ``wind_case`` = 1 or 2 gives the
   case instead: a diagnostic, not the paper's method.)
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

import numpy as np

from service.farm.cusum import PaperCusum, llr_increment
from service.farm.interfaces import BETA, N_TYPES, OMEGA_G, P_G, FarmContext, FarmDiagnosis, FarmSample
from service.farm.power_curve import available_power, power_from_speed, speed_from_power
from service.farm.signals import LockIn3P, MastDelays
from wwcore.scenario.farm import FARM_DT_S, N_TURBINES, ROTOR_DIAMETER_M

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


def row_matrices(rows: list[tuple[int, ...]]) -> tuple[np.ndarray, np.ndarray]:
    """(M, alone): M[t, u] = 1/(|row| − 1) for the other turbines u of t's row, alone[t] when t has none."""
    m = np.zeros((N_TURBINES, N_TURBINES))
    alone = np.zeros(N_TURBINES, dtype=bool)
    for row in rows:
        for t in row:
            others = [u for u in row if u != t]
            alone[t - 1] = not others
            for u in others:
                m[t - 1, u - 1] = 1.0 / len(others)
    return m, alone


class PaperDetector:
    """Seed 001's detector, vectorised over farms (module docstring)."""

    def __init__(self, *, context: FarmContext, options: dict | None = None):
        options = options or {}
        self.context = context
        self.p = context.params
        n, farms = context.n, context.farms
        self.n, self.farms = n, farms
        given = options.get("wind_case")
        self.case = np.full(farms, int(given) if given is not None else 0)  # 0: not yet estimated
        self._p14 = np.zeros(farms)  # Σ (P_1 − P_4) over the first 500 samples
        self._samples = 0
        self._matrices = {c: row_matrices(context.rows(c)) for c in (1, 2)}
        self._row_of = {}
        for c in (1, 2):
            row_of = np.zeros(N_TURBINES, dtype=int)
            for i, row in enumerate(context.rows(c)):
                row_of[[t - 1 for t in row]] = i
            self._row_of[c] = row_of
        self._distances = {c: context.mast_distance_m + np.array(context.row_distances_m(c)) for c in (1, 2)}
        self.mast = MastDelays(farms)
        self.lockin = LockIn3P(n, LOCKIN_TAU_S)
        self.p_ag: np.ndarray | None = None  # eq. (12) state
        self.cusum = [
            PaperCusum((n,), H1[0], H0[0]),
            PaperCusum((n, 3), H1[1], H0[1]),
            PaperCusum((n,), H1[2], H0[2]),
        ]
        self.reported = np.full(farms, -1)  # per farm: index type·9 + (t − 1) of the reported fault, −1 none
        self.residuals = np.zeros((n, N_TYPES))

    def step(self, sample: FarmSample) -> FarmDiagnosis:
        p, n, farms = self.p, self.n, self.farms
        y = sample.scada
        self.mast.step(sample.mast)
        power = y[:, P_G]
        omega_g = y[:, OMEGA_G].mean(axis=1)
        amplitude = self.lockin.step(omega_g, omega_g / p.N_g)
        # eqs. (1)–(2): wind direction from the first 500 samples
        if self._samples < CASE_SAMPLES and (self.case == 0).any():
            per = power.reshape(farms, N_TURBINES)
            self._p14 += per[:, 0] - per[:, 3]
            if self._samples + 1 == CASE_SAMPLES:
                p_wm = np.abs(self._p14 / CASE_SAMPLES)
                self.case = np.where(self.case == 0, np.where(p_wm <= CASE_THRESHOLD_W, 1, 2), self.case)
        self._samples += 1
        diagnosis = FarmDiagnosis(
            np.zeros((n, N_TYPES), dtype=bool), np.zeros((n, N_TYPES)), np.tile(np.array(H1), (n, 1))
        )
        if (self.case == 0).any():
            return diagnosis
        m = np.stack([self._matrices[1][0], self._matrices[2][0]])  # (2, 9, 9)
        alone = np.stack([self._matrices[1][1], self._matrices[2][1]])  # (2, 9)
        sel = (self.case == 1)[:, None]
        alone_t = np.where(sel, alone[0], alone[1]).reshape(-1)  # (n,)

        def row_mean_others(x: np.ndarray) -> np.ndarray:  # (n,) → (n,) mean over the row's other turbines
            xf = x.reshape(farms, N_TURBINES)
            return np.where(sel, xf @ m[0].T, xf @ m[1].T).reshape(-1)

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
        v_case = [self.mast.delayed(self._distances[c])[:, self._row_of[c]] for c in (1, 2)]  # (farms, 9) each
        v_est = np.where(sel, v_case[0], v_case[1]).reshape(-1)  # (n,) the wind at each turbine's row, eq. (3)
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
        diagnosis.extra = {"wind_case": np.repeat(self.case, N_TURBINES), "amplitude_3p": amplitude}
        return diagnosis

    def _one_at_a_time(self, flags: np.ndarray) -> np.ndarray:
        """Section 3.7: per farm, report the first flag to rise until it falls."""
        farms = self.farms
        per = flags.reshape(farms, N_TURBINES, N_TYPES).transpose(0, 2, 1).reshape(farms, -1)  # (farms, type·9 + t)
        still = (self.reported >= 0) & per[np.arange(farms), np.maximum(self.reported, 0)]
        first = np.where(per.any(axis=1), per.argmax(axis=1), -1)
        self.reported = np.where(still, self.reported, first)
        out = np.zeros((farms, N_TYPES * N_TURBINES), dtype=bool)
        has = self.reported >= 0
        out[np.flatnonzero(has), self.reported[has]] = True
        return out.reshape(farms, N_TYPES, N_TURBINES).transpose(0, 2, 1).reshape(-1, N_TYPES)
