"""Parameters of the 4.8 MW FDI/FTC benchmark turbine (Odgaard, Stoustrup & Kinnaert 2009).

Every number comes from ``shared/reference/PARAMETERS.md`` section a; the tag after each field says where it
comes from there ([BENCH] benchmark script/model, [DERIVED] computed, [PROPOSED] our choice).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(frozen=True)
class PitchActuatorParams:
    """Second-order pitch actuator ω_n²/(s² + 2ζω_n s + ω_n²)."""

    omega_n: float = 11.11  # rad/s [BENCH] omega_n
    zeta: float = 0.6  # – [BENCH] xi


@dataclass(frozen=True)
class TurbineParams:
    """The benchmark turbine. SI units; pitch angles in degrees where the benchmark uses degrees."""

    rated_power: float = 4.8e6  # W [BENCH] P_r
    dt: float = 0.01  # s, controller/sensor sample time [BENCH] Ts
    radius: float = 57.5  # m [BENCH] R
    hub_height: float = 87.0  # m [BENCH] H
    rho: float = 1.225  # kg/m³ [BENCH] rho
    J_r: float = 55e6  # kg m² rotor inertia [BENCH]
    J_g: float = 390.0  # kg m² generator inertia [BENCH]
    K_dt: float = 2.7e9  # N m/rad torsion stiffness [BENCH]
    B_dt: float = 775.49  # N m s/rad torsion damping [BENCH]
    B_r: float = 7.11  # N m s/rad rotor friction [BENCH]
    B_g: float = 45.6  # N m s/rad generator friction [BENCH]
    N_g: float = 95.0  # – gear ratio [BENCH]
    eta_dt: float = 0.97  # – drive-train efficiency [BENCH]
    pitch: PitchActuatorParams = field(default_factory=PitchActuatorParams)
    pitch_min_deg: float = -2.0  # deg [BENCH] saturation
    pitch_max_deg: float = 90.0  # deg [BENCH] saturation
    alpha_gc: float = 50.0  # rad/s converter bandwidth [BENCH] 1/20e-3
    eta_gc: float = 0.98  # – generator/converter efficiency [BENCH]
    omega_nom: float = 162.0  # rad/s rated generator speed [BENCH] Omega_nom
    omega_delta: float = 15.0  # rad/s hysteresis back to region 2 [BENCH] Omega_delta
    cp_max: float = 0.4554  # – [BENCH] C_p,max of the reference surface
    lambda_opt: float = 8.0  # – [BENCH]
    K_p: float = 4.0  # deg/(rad/s) region-3 pitch PI [BENCH]
    K_i: float = 1.0  # deg/(rad s) [BENCH]
    tower_radius: float = 1.5  # m, r0 of the tower-shadow model [BENCH]
    initial_omega_r: float = 1.0  # rad/s [BENCH] integrator IC
    initial_omega_g: float = 100.0  # rad/s [BENCH] integrator IC

    @property
    def k_opt(self) -> float:
        """Region-2 gain K_opt = ½ρπR⁵η_dt C_p,max/(N_g λ_opt)³ in N m/(rad/s)² on the generator side [DERIVED]."""
        r = self.radius
        return 0.5 * self.rho * math.pi * r**2 * self.eta_dt * r**3 * self.cp_max / (self.N_g * self.lambda_opt) ** 3

    @property
    def rated_torque(self) -> float:
        """Generator torque at rated power and speed, P_r/(η_gc Ω_nom), N m [DERIVED]."""
        return self.rated_power / (self.eta_gc * self.omega_nom)

    @property
    def aero_torque_gain(self) -> float:
        """ρπR³/2: rotor torque τ_r = gain · C_q(λ, β) · v², N m/(m/s)² (a.2, summed over three blades)."""
        return 0.5 * self.rho * math.pi * self.radius**3

    @property
    def drivetrain_eigenfrequency_hz(self) -> float:
        """Undamped torsion mode √(K_dt/J_eq)/2π with J_eq = J_r J_g N² / (J_r + J_g N²), Hz [DERIVED]."""
        jg_low = self.J_g * self.N_g**2
        j_eq = self.J_r * jg_low / (self.J_r + jg_low)
        return math.sqrt(self.K_dt / j_eq) / (2.0 * math.pi)


BENCHMARK = TurbineParams()
"""The benchmark turbine with its published parameters."""
