"""Parameters of the wind turbine with hydrostatic transmission (seed 003, Schulte & Gauterin 2015).

The paper publishes no parameter set. The numbers below are ``shared/reference/PARAMETERS.md`` section c,
an NREL-5-MW-sized rotor with a pump/motor pair sized so that the rated point is self-consistent. The tag after
each field says where it comes from: [PAPER] the paper, [PROPOSED] PARAMETERS.md c or our own choice (with the
reason), [DERIVED] computed from the others.

Notation: x̃_p and x̃_M are the *normalised displacements* of the hydraulic pump and motor (swash-plate
positions, eqs. (1)–(2)), not pitch angles. Pitch stays at β = 0 in partial load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace


@dataclass(frozen=True)
class BaselineControllerParams:
    """The baseline controller of Section 3 (Fig. 2): eqs. (18)–(20) plus a PI on the generator speed.

    The PI acts on the demanded transmission ratio: r_cv,d = ω_g,N/ω_r + K_p e + K_i ∫e dt, e = ω_g,N − ω_g.
    r_cv,d then sets the displacements through (19) and the torque demand through (18). Gains [PROPOSED], chosen
    by linearising the closed loop (``tests/hydro/test_controller.py``): the generator–pressure mode sits at
    2–3.5 rad/s with ζ ≈ 0.1 (``HydroParams.hydraulic_mode``) and the step from x̃_M to ω_g has a right-half-plane
    zero (less motor stroke first unloads the generator), so the loop must stay slow. K_p = 0.3, K_i = 0.1 keep
    every eigenvalue in the left half-plane over v = 5.5 … 10 m/s, fault-free and with offsets up to −0.4 on either
    displacement; larger K_i (≥ 0.2) or K_p (≥ 0.5) destabilise the hydraulic mode under motor faults.
    """

    K_p: float = 0.3  # (unit ratio)/(rad/s) [PROPOSED]
    K_i: float = 0.1  # (unit ratio)/(rad) [PROPOSED]
    r_cv_min: float = 40.0  # – lower clamp of r_cv,d (x̃_M ≤ 2.4 before the stroke clamp) [PROPOSED]
    r_cv_max: float = 400.0  # – upper clamp of r_cv,d (x̃_M ≥ 0.24) [PROPOSED]
    integral_limit: float = 60.0  # – anti-windup clamp of the PI integral, in ratio units [PROPOSED]


@dataclass(frozen=True)
class Envelope:
    """Operating envelope over which the TS premise bounds (eq. 9) are taken [PROPOSED].

    Partial load with margin for turbulence and for the transients of the faults the paper simulates
    (ω_r 0.7 … 1.2 rad/s nominally, Section 3.2; a −0.4 motor fault drives ω_g well above ω_g,N).
    """

    v_min: float = 3.0  # m/s
    v_max: float = 16.0  # m/s
    omega_r_min: float = 0.3  # rad/s
    omega_r_max: float = 2.0  # rad/s
    omega_g_min: float = 40.0  # rad/s
    omega_g_max: float = 320.0  # rad/s
    x_p_min: float = 0.1  # – normalised pump displacement
    x_p_max: float = 1.6  # –
    x_M_min: float = 0.1  # – normalised motor displacement
    x_M_max: float = 1.6  # –


@dataclass(frozen=True)
class HydroParams:
    """The plant of eq. (4). SI units throughout."""

    # rotor and aerodynamics
    rho: float = 1.225  # kg/m³ air density [PROPOSED] NREL 5 MW
    radius: float = 63.0  # m rotor radius R [PROPOSED] NREL 5 MW
    J_r: float = 3.8759e7  # kg m² rotor and hub inertia [PROPOSED] NREL 5 MW
    cp_max: float = 0.482  # – C_p,max of the analytic map [PROPOSED] NREL-5-MW-like
    lambda_opt: float = 7.55  # – tip speed ratio of C_p,max [PROPOSED]
    # generator
    J_g: float = 570.0  # kg m² generator (534) + hydraulic motor [PROPOSED]
    omega_g_N: float = 122.5  # rad/s nominal generator speed ω_g,N [PAPER]
    tau_g: float = 0.02  # s generator torque lag τ_g [PROPOSED]
    # hydrostatic transmission
    V_p: float = 0.139  # m³/rad pump displacement Ṽ_p = V_p/2π (= 4.18e6 N m / Δp_N) [PROPOSED]
    V_M: float = 1.44e-3  # m³/rad motor displacement Ṽ_M [PROPOSED]
    k_leak: float = 1.76e-10  # m³/(s Pa) lumped leakage, 3 % volumetric loss at rated [PROPOSED]
    C_H: float = 3.33e-10  # m³/Pa hydraulic capacitance, 0.4 m³ oil at 1.2e9 Pa bulk modulus [PROPOSED]
    dp_rated: float = 3.0e7  # Pa rated pressure difference Δp_N [PROPOSED]
    dp_max: float = 3.5e7  # Pa pressure limit (reported, not enforced: the paper's model has no relief valve)
    tau_p: float = 0.1  # s pump displacement lag τ_p [PROPOSED]
    tau_M: float = 0.1  # s motor displacement lag τ_M [PROPOSED]
    # Stroke limits of the displacement units. [PROPOSED] decision: x̃ = 1 is the *rated* stroke the controller
    # uses (eq. (19) never commands more), the mechanical stop is at 1.5. With the stop at 1 (eq. (1) read
    # literally) a −0.2 pump offset at full stroke cannot be compensated by (36), and after the fault ends the
    # compensated command stays clipped, which makes the offset unobservable; see docs/hydro.md.
    stroke_min: float = 0.05  # – [PROPOSED] keeps x̃_M away from 0 (ω_g ∝ 1/x̃_M)
    stroke_max: float = 1.5  # – [PROPOSED]
    # operation
    omega_r_cut_in: float = 0.5  # rad/s rotor speed below which (20) is held [PROPOSED]
    omega_r_rated: float = 1.267  # rad/s rated rotor speed (12.1 rpm) [PROPOSED] NREL 5 MW
    dt: float = 0.01  # s controller and sensor sample time, 100 Hz [PROPOSED] as the benchmark turbine
    controller: BaselineControllerParams = field(default_factory=BaselineControllerParams)
    envelope: Envelope = field(default_factory=Envelope)

    @property
    def k_opt(self) -> float:
        """Optimal-torque gain ½ρπR⁵C_p,max/λ_opt³ on the rotor shaft, N m s² (eq. 18) [DERIVED] ≈ 2.14e6."""
        return 0.5 * self.rho * math.pi * self.radius**5 * self.cp_max / self.lambda_opt**3

    @property
    def aero_gain(self) -> float:
        """½ρπR³ of eq. (5): T_r = aero_gain · v² · C_Q(λ, β), N m/(m/s)² [DERIVED]."""
        return 0.5 * self.rho * math.pi * self.radius**3

    @property
    def ratio_max_displacement(self) -> float:
        """Ṽ_p/Ṽ_M, the transmission ratio at x̃_p = x̃_M = 1 (eq. 3) [DERIVED] ≈ 96.5."""
        return self.V_p / self.V_M

    @property
    def rated_rotor_torque(self) -> float:
        """Ṽ_p Δp_N, the rotor torque the pump holds at rated pressure and full stroke, N m [DERIVED] ≈ 4.17e6."""
        return self.V_p * self.dp_rated

    @property
    def rated_generator_torque(self) -> float:
        """Ṽ_M Δp_N, the motor torque at rated pressure and full stroke, N m [DERIVED] ≈ 4.32e4."""
        return self.V_M * self.dp_rated

    def hydraulic_mode(self, x_M: float = 0.8) -> tuple[float, float]:
        """Undamped frequency (rad/s) and damping ratio of the generator–pressure mode at motor stroke ``x_M``.

        ω_n² = (Ṽ_M x̃_M)²/(C_H J_g) + (Ṽ_p)²/(C_H J_r), 2ζω_n = k_leak/C_H [DERIVED]. With these parameters the
        mode sits at 2–3.5 rad/s: C_H is small, but so are the coupling terms, so the pressure state is not stiff.
        """
        w2 = (self.V_M * x_M) ** 2 / (self.C_H * self.J_g) + self.V_p**2 / (self.C_H * self.J_r)
        wn = math.sqrt(w2)
        return wn, self.k_leak / self.C_H / (2.0 * wn)

    def with_uncertainty(self, leak_factor: float = 1.0) -> HydroParams:
        """The plant's true parameters under the leakage uncertainty of eq. (16): k_leak = k_leak,n (1 + Δ)."""
        return replace(self, k_leak=self.k_leak * leak_factor)


NOMINAL = HydroParams()
"""The nominal parameter set (PARAMETERS.md c)."""

Y_NAMES: tuple[str, ...] = ("omega_r", "omega_g", "T_g", "x_p", "x_M")
"""Measured outputs y of eq. (4), column order of every sensor array."""
Y_UNITS: tuple[str, ...] = ("rad/s", "rad/s", "N m", "-", "-")
U_NAMES: tuple[str, ...] = ("u_p", "u_M", "T_g_d")
"""Controller commands u, column order of every command array (the paper's text lists T_g first; we follow (7))."""
X_NAMES: tuple[str, ...] = ("omega_r", "omega_g", "dp", "T_g", "x_p", "x_M")
"""States x of eq. (4)."""
FAULT_TARGETS: tuple[str, ...] = ("u_p", "u_M")
"""The actuators a hydrostatic fault can hit (offsets on the displacement commands), columns of f_a."""
