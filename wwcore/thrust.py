r"""Thrust coefficient of the benchmark rotor from its operating point: a loss-corrected actuator disc.

The benchmark publishes C_p(λ, β) and C_q(λ, β) but no thrust. One-dimensional momentum theory ties thrust to
power through the axial induction a: C_T = 4a(1 − a) and, for an ideal rotor, C_p = C_T (1 − a) = 4a(1 − a)².
Read backwards on a real rotor's C_p this underestimates thrust badly (C_p = 0.44 gives C_T = 0.52), because a
real rotor turns only a fraction η of the ideal disc's power into shaft power (profile drag, tip losses, wake
rotation) while carrying the thrust. A pitch-regulated turbine runs near C_T ≈ 0.8 below rated.

**Model.** The rotor's loading is read from its power coefficient relative to its own maximum:

.. math::  h(C_T) \equiv C_T \,\frac{1 + \sqrt{1 - C_T}}{2} = 4a(1-a)^2 = K\,\frac{C_p}{C_{p,\max}},
           \qquad a \in [0, 1/3]

so C_T = h⁻¹(K C_p / C_p,max), with h⁻¹ taken on the branch a ≤ 1/3 (h ≤ 16/27; larger values are clipped, C_T ≤
8/9). K = h(C_T at C_p,max) is one constant, fitted by least squares (``tools/fit_thrust.py``) to the published
power and thrust curves of five pitch-regulated turbines from their C_p maximum to cut-out: the NREL 5 MW, IEA
10 MW, IEA 15 MW and IEA 22 MW reference turbines (as shipped in FLORIS 4.7's turbine library) and the Vestas V80
(``shared/data/v80_reference_curves.csv``, DTU's PyWake Horns Rev 1 example). Normalising by each turbine's own
C_p,max removes its efficiency level; what is left collapses onto one curve:

==========================================  ==============================
fitted K                                    0.5754 (C_T = 0.788 at C_p,max)
RMS |ΔC_T| over 131 curve points             0.025
per turbine RMS (max)                       NREL 5 MW 0.019 (0.043), IEA 10 MW 0.016 (0.039),
                                            IEA 15 MW 0.021 (0.055), IEA 22 MW 0.024 (0.051),
                                            V80 0.046 (0.17, at 12 m/s, where its curve drops 0.71 → 0.41 in 1 m/s)
independent check: NREL 5 MW C_T(λ, β)       RMS 0.048 over λ 4–9.5, β ≥ −1 deg, C_p > 0.02 (341 points; worst
surface (FLORIS's controller-dependent         0.29 at λ = 9.5, β = −1 deg, an over-speed corner the benchmark never
model data), not used in the fit              reaches); λ ≤ 8: RMS 0.036, 95 % within 0.06, max 0.105 (β = −1 deg)
==========================================  ==============================

For the benchmark, C_p,max is that of the project's aerodynamic model (``wwcore.aero``, 0.4584). Along its steady
operating curve this gives C_T ≈ 0.71 at 7 m/s, 0.74 at 9 m/s, 0.75 at 11–13 m/s (the benchmark's region-2 torque
law holds λ ≈ 7.1–7.4, a little below λ_opt = 8, so C_p/C_p,max ≈ 0.95–0.98), then 0.42 at 15 m/s, 0.19 at 19 m/s
and 0.08 at 25 m/s.

**Derated and curtailed operation.** The rule reads the operating point, not the wind: a turbine asked for less
power than it could make pitches (and, under the farm controller, slows) to a lower C_p, and its thrust falls along
the same curve the reference turbines follow above rated, where they shed power the same way. At 8 m/s the
benchmark's C_T is 0.73 at its available power, 0.55 at 80 % of it (pitch 4.1 deg) and 0.35 at 50 % (8.5 deg);
at 14 m/s 0.54, 0.42 and 0.26 (``tools/fit_thrust.py``).

**Limits.** One variable cannot tell how a given C_p was reached: at the same C_p a rotor slowed below λ_opt and a
rotor pitched at λ_opt carry somewhat different thrust (the NREL surface check above: RMS 0.036 for λ ≤ 8). The
fit says nothing about stall-side (negative) pitch, idling or start-up (C_p < 0.02); there C_T simply follows C_p
to 0. The C_T of a yawed rotor is not modelled.
"""

from __future__ import annotations

import functools

import numpy as np

from wwcore import aero

THRUST_LOADING_K = 0.5754  # – h(C_T) at C_p = C_p,max, fitted by tools/fit_thrust.py (see the module docstring)
H_MAX = 16.0 / 27.0  # – largest h = 4a(1 − a)², at a = 1/3 (the Betz point)
_A_GRID = np.linspace(0.0, 1.0 / 3.0, 4001)
_CT_GRID = 4.0 * _A_GRID * (1.0 - _A_GRID)
_H_GRID = _CT_GRID * (1.0 - _A_GRID)  # increasing on [0, 1/3]


def loading_function(ct: np.ndarray) -> np.ndarray:
    """h(C_T) = C_T (1 + √(1 − C_T)) / 2 = 4a(1 − a)² with a = (1 − √(1 − C_T))/2."""
    ct = np.clip(np.asarray(ct, dtype=float), 0.0, 1.0)
    return ct * (1.0 + np.sqrt(1.0 - ct)) / 2.0


def axial_induction(ct: np.ndarray) -> np.ndarray:
    """a = (1 − √(1 − C_T))/2, the actuator disc's axial induction."""
    return (1.0 - np.sqrt(1.0 - np.clip(np.asarray(ct, dtype=float), 0.0, 1.0))) / 2.0


@functools.cache
def model_cp_max() -> float:
    """C_p,max of the project's aerodynamic model (``wwcore.aero``), by a grid search refined to 0.005 in λ, β."""
    lam, beta = np.meshgrid(np.linspace(6.0, 10.0, 401), np.linspace(-2.0, 2.0, 161), indexing="ij")
    return float(np.max(aero.power_coefficient(lam, beta)))


def thrust_from_power_coefficient(
    cp: np.ndarray, cp_max: float | None = None, loading: float = THRUST_LOADING_K
) -> np.ndarray:
    """C_T = h⁻¹(K C_p / C_p,max) on the branch a ≤ 1/3; C_p ≤ 0 gives 0, h is clipped at 16/27 (C_T ≤ 8/9).

    ``cp_max`` defaults to the project's aerodynamic model's; ``loading`` is K.
    """
    cp_max = model_cp_max() if cp_max is None else cp_max
    h = np.clip(loading * np.asarray(cp, dtype=float) / cp_max, 0.0, H_MAX)
    return np.interp(h, _H_GRID, _CT_GRID)


def thrust_coefficient(tsr: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """C_T of the benchmark rotor at tip-speed ratio λ and collective pitch β (deg): h⁻¹(K C_p(λ, β)/C_p,max)."""
    return thrust_from_power_coefficient(aero.power_coefficient(np.asarray(tsr), np.asarray(pitch_deg)))
