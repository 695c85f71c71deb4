r"""The plant's own parameters where they differ from the design model (``wwcore.scenario.mismatch``), per row.

A scenario's ``[mismatch]`` section is resolved here into per-row arrays (rows = Monte Carlo runs × turbines, and
their fault-free twins) that the turbine batch applies:

* aerodynamics, with s = ``cp_scale``, Δλ = ``tsr_shift``, ρ = ``air_density_kgm3`` (ρ_0 = 1.225 kg/m³):

  .. math::

      C_{p,plant}(λ, β) = s\, C_p(λ − Δλ, β),\qquad
      τ_{r,i} = \frac{ρ}{ρ_0}\,\frac{ρ_0 π R^3}{6}\, \frac{C_{p,plant}(λ_i, β_i)}{λ_i}\, v_i^2

  so the plant's C_p,max is s C_p,max at λ_opt + Δλ, and the torque scales with ρ/ρ_0 at a fixed operating point
  (PARAMETERS.md a.2 with the plant's ρ and surface). Below λ_e = 1 + |Δλ| the plant's C_q is held at its value at
  λ_e (the design surface holds C_q below λ = 1 the same way, ``wwcore.aero``), so the starting torque is bounded;
  the operating envelope λ ≥ 2 is unaffected for |Δλ| ≤ 1.
* drive train: K_dt × ``drivetrain_stiffness_factor``; B_dt chosen so that the plant's torsion mode has the
  damping ratio ζ = ``drivetrain_damping_ratio`` (``torsion_damping``; the design model's is ≈ 0.0019).
* pitch actuators: ω_n²/(s² + 2ζω_n s + ω_n²) with the plant's ω_n, ζ, per blade.
* sensors: σ_plant = σ × noise scale per channel, and a calibration bias b added to every reading.

Draws (``[mismatch.spread]``): row r of turbine t in run m draws ``N_SLOTS`` numbers u ∈ U(−1, 1) from its own
stream ``SeedSequence(seed, spawn_key=(m, t, MISMATCH_STREAM))``, a sibling of the wind and noise streams of
``plant.row_streams`` (which spawn children 0 and 1 of the same key), so the draws never move the wind or the
noise. Every field has its fixed slots (``SLOTS``) whatever the spread, so changing one spread changes only that
field's values. Twin rows share their run's draws: the same plant without its faults.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from plant_sim.turbine.dynamics import torsion_mode
from wwcore.channels import N_SENSORS, SENSOR_INDEX, SENSOR_NAMES
from wwcore.scenario.mismatch import SENSOR_BIAS_TOLERANCE, Mismatch, MismatchValues
from wwcore.turbine_params import TurbineParams

MISMATCH_STREAM = 2  # spawn-key suffix of the mismatch draws; 0 and 1 are a row's wind and noise streams

# Slots of the uniform draws, in order: one per scalar, three per pitch quantity (blades), one per sensor.
SLOTS: dict[str, slice] = {}
_start = 0
for _name, _width in (
    ("cp_scale", 1),
    ("tsr_shift", 1),
    ("air_density_kgm3", 1),
    ("drivetrain_stiffness_factor", 1),
    ("drivetrain_damping_ratio", 1),
    ("pitch_omega_n_rads", 3),
    ("pitch_zeta", 3),
    ("noise_scale", N_SENSORS),
    ("sensor_bias", N_SENSORS),
):
    SLOTS[_name] = slice(_start, _start + _width)
    _start += _width
N_SLOTS = _start


def equivalent_inertia(p: TurbineParams) -> float:
    """J_eq = J_r J_g N_g² / (J_r + J_g N_g²), kg m² on the low-speed side: the torsion mode's inertia."""
    jg_low = p.J_g * p.N_g**2
    return p.J_r * jg_low / (p.J_r + jg_low)


def torsion_damping(p: TurbineParams, ratio: float, stiffness_factor: float) -> float:
    """B_dt (N m s/rad) that gives the plant's torsion mode the damping ratio ζ = ``ratio`` (–).

    The mode's ζ is read from the eigenvalues of the drive train's [ω_r, ω_g, θ_Δ] block (``torsion_mode``), so
    the friction B_r, B_g and η_dt count: with B_dt = 0 they alone give ζ ≈ 0.0019 at the design stiffness (0.0023
    at 0.7 K_dt), which is why ``LIMITS`` starts at 0.0025. Solved by bisection in B_dt (ζ rises monotonically).
    """
    b_floor = torsion_mode(p, stiffness_factor, 0.0)[0]
    if ratio <= b_floor:
        return 0.0
    scale = 2.0 * math.sqrt(p.K_dt * stiffness_factor * equivalent_inertia(p))  # B_dt per unit of shaft-only ζ
    return brentq(lambda b: torsion_mode(p, stiffness_factor, b / p.B_dt)[0] - ratio, 0.0, 2.0 * ratio * scale)


@dataclass
class RowMismatch:
    """The plant's quantities of every row (``resolve``); the design model's values where nothing differs."""

    cp_scale: np.ndarray  # (n,) –
    tsr_shift: np.ndarray  # (n,) –
    density_ratio: np.ndarray  # (n,) ρ/ρ_0
    stiffness_factor: np.ndarray  # (n,) K_dt,plant / K_dt
    damping_factor: np.ndarray  # (n,) B_dt,plant / B_dt
    pitch_omega_n: np.ndarray  # (n, 3) rad/s
    pitch_zeta: np.ndarray  # (n, 3) –
    noise_scale: np.ndarray  # (n, N_SENSORS) –
    bias: np.ndarray  # (n, N_SENSORS) in each channel's unit

    @property
    def aero_factor(self) -> np.ndarray:
        """(n,) s ρ/ρ_0: multiplies the design model's blade torque gain."""
        return self.cp_scale * self.density_ratio

    @property
    def shifted(self) -> bool:
        """True when some row's C_p surface is moved in λ (the plant then evaluates ``plant_torque_coefficient``)."""
        return bool(np.any(self.tsr_shift != 0.0))

    @property
    def aero_nominal(self) -> bool:
        return not self.shifted and bool(np.all(self.aero_factor == 1.0))

    @property
    def noise_nominal(self) -> bool:
        return bool(np.all(self.noise_scale == 1.0))

    @property
    def bias_nominal(self) -> bool:
        return bool(np.all(self.bias == 0.0))

    @property
    def pitch_a0(self) -> np.ndarray:
        """(n, 3) ω_n², 1/s²."""
        return self.pitch_omega_n**2

    @property
    def pitch_a1(self) -> np.ndarray:
        """(n, 3) 2ζω_n, 1/s."""
        return 2.0 * self.pitch_zeta * self.pitch_omega_n


def nominal(p: TurbineParams, n: int) -> RowMismatch:
    """n rows of the design model itself."""
    return RowMismatch(
        cp_scale=np.ones(n),
        tsr_shift=np.zeros(n),
        density_ratio=np.ones(n),
        stiffness_factor=np.ones(n),
        damping_factor=np.ones(n),
        pitch_omega_n=np.full((n, 3), p.pitch.omega_n),
        pitch_zeta=np.full((n, 3), p.pitch.zeta),
        noise_scale=np.ones((n, N_SENSORS)),
        bias=np.zeros((n, N_SENSORS)),
    )


def mismatch_draws(seed: int, run: int, turbine: int) -> np.ndarray:
    """The N_SLOTS uniform numbers in (−1, 1) of one turbine in one run (module docstring)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, turbine, MISMATCH_STREAM)))
    return rng.uniform(-1.0, 1.0, N_SLOTS)


def resolve(
    spec: Mismatch | None, p: TurbineParams, seed: int, run_of_row: np.ndarray, turbine_of_row: np.ndarray
) -> RowMismatch:
    """Per-row plant quantities for the rows (run, turbine) of a batch; ``spec`` None is the design model."""
    n = len(run_of_row)
    out = nominal(p, n)
    if spec is None:
        return out
    spread = spec.spread
    random = any(getattr(spread, name) > 0.0 for name in type(spread).model_fields)
    for row, (run, turbine) in enumerate(zip(run_of_row, turbine_of_row, strict=True)):
        centre = spec.centre(int(turbine))
        u = mismatch_draws(seed, int(run), int(turbine)) if random else np.zeros(N_SLOTS)
        _fill_row(out, row, centre, spread, u, p)
    return out


def _value(centre: MismatchValues, spread, name: str, u: np.ndarray, default: float) -> np.ndarray:
    """Centre (``default`` when not given) + u × half-width over one field's slots, shape (slot width,)."""
    value = getattr(centre, name)
    base = np.full(SLOTS[name].stop - SLOTS[name].start, default if value is None else value)
    half = getattr(spread, name)
    return base if half == 0.0 else base + half * u[SLOTS[name]]


def _fill_row(out: RowMismatch, row: int, centre: MismatchValues, spread, u: np.ndarray, p: TurbineParams) -> None:
    out.cp_scale[row] = _value(centre, spread, "cp_scale", u, 1.0)[0]
    out.tsr_shift[row] = _value(centre, spread, "tsr_shift", u, 0.0)[0]
    out.density_ratio[row] = _value(centre, spread, "air_density_kgm3", u, p.rho)[0] / p.rho
    stiffness = _value(centre, spread, "drivetrain_stiffness_factor", u, 1.0)[0]
    out.stiffness_factor[row] = stiffness
    if centre.drivetrain_damping_ratio is not None or spread.drivetrain_damping_ratio > 0.0:
        ratio = _value(centre, spread, "drivetrain_damping_ratio", u, _benchmark_ratio(p))[0]
        out.damping_factor[row] = torsion_damping(p, max(ratio, 0.0), stiffness) / p.B_dt
    out.pitch_omega_n[row] = _value(centre, spread, "pitch_omega_n_rads", u, p.pitch.omega_n)
    out.pitch_zeta[row] = _value(centre, spread, "pitch_zeta", u, p.pitch.zeta)
    scale = np.full(N_SENSORS, 1.0 if centre.noise_scale is None else centre.noise_scale)
    for sensor, value in centre.sensor_noise_scale.items():
        scale[SENSOR_INDEX[sensor]] = value
    if spread.noise_scale > 0.0:
        scale = scale + spread.noise_scale * u[SLOTS["noise_scale"]]
    out.noise_scale[row] = scale
    bias = np.zeros(N_SENSORS)
    for sensor, value in centre.sensor_bias.items():
        bias[SENSOR_INDEX[sensor]] = value
    if spread.sensor_bias_fraction > 0.0:
        tolerance = np.array([SENSOR_BIAS_TOLERANCE[name] for name in SENSOR_NAMES])
        bias = bias + spread.sensor_bias_fraction * tolerance * u[SLOTS["sensor_bias"]]
    out.bias[row] = bias


def _benchmark_ratio(p: TurbineParams) -> float:
    """The design model's own torsion-mode damping ratio (≈ 0.0019, mostly the generator friction)."""
    return torsion_mode(p, 1.0, 1.0)[0]
