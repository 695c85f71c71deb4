"""The benchmark's turbine controller (PARAMETERS.md a.1–a.2, Simulink block "Controller"), vectorised.

Zone logic (Embedded MATLAB ``ZoneControl``, previous zone held in a unit delay)::

    if last == 0: zone = 1 if (P_g ≥ P_r or ω_g ≥ Ω_nom) else 0
    else:         zone = 0 if ω_g < Ω_nom − Ω_Δ else 1

Zone 0 (region 2): β_ref = 0, τ_g,r = K_opt ω_g².
Zone 1 (region 3): β_ref = sat(K_p e + K_i I), e = ω_g − Ω_nom, I = sat(∫e dt, −2, 90); τ_g,r = P_r/(η_gc ω_g).

The integrator runs in both zones (in region 2 e < 0 drives it to its lower limit), so re-entering region 3
starts from β_ref ≈ K_p e − 2 deg rather than from a stale value. The controller runs at Ts with a zero-order
hold; P_r is the turbine's power reference (rated, or the farm dispatch's per-turbine reference).
"""

from __future__ import annotations

import numpy as np

from wwcore.backend import fast_module, resolve_backend
from wwcore.turbine_frames import TurbineRefs
from wwcore.turbine_params import TurbineParams


class BenchmarkController:
    """Region 2/3 controller for n turbines. ``step`` is called once per tick; ``backend`` as ``wwcore.backend``
    (``"numba"``: the zone logic and laws by ``plant_sim.turbine.fast.control``, the same numbers)."""

    def __init__(
        self, params: TurbineParams, n: int, power_reference: float, max_ref_age: int = 10, backend: str | None = None
    ):
        self.p = params
        self._fast = fast_module("plant_sim.turbine.fast") if resolve_backend(backend) == "numba" else None
        p = params
        self._constants = (p.omega_nom, p.omega_delta, p.dt, p.pitch_min_deg, p.pitch_max_deg, p.K_p, p.K_i)
        self._constants += (p.eta_gc, p.k_opt)
        self.n = n
        self.max_ref_age = max_ref_age  # ticks after which the supervisor's references count as stale
        self.zone = np.zeros(n, dtype=np.int8)
        self.integrator = np.full(n, params.pitch_min_deg)
        self.power_ref = np.full(n, float(power_reference))
        self.tau_g_ref = np.zeros(n)
        self.beta_ref = np.zeros(n)
        self.pitch_trim: np.ndarray | None = None  # (n, 3) deg added to each blade's command (None: no trim)
        self.using_estimates = np.zeros(n, dtype=bool)

    def initialise(self, zone: np.ndarray, beta_ref: np.ndarray, tau_g_ref: np.ndarray) -> None:
        """Start from a trimmed operating point (see ``TurbineBatch``)."""
        self.zone[:] = zone
        self.integrator[:] = np.clip(beta_ref, self.p.pitch_min_deg, self.p.pitch_max_deg)
        self.beta_ref[:] = beta_ref
        self.tau_g_ref[:] = tau_g_ref

    def _take(self, k: int, refs: TurbineRefs | None) -> bool:
        """Whether ``refs`` are fresh at tick k; the rows that use their estimates, their power references taken."""
        fresh = refs is not None and 0 <= k - refs.tick <= self.max_ref_age
        if fresh:
            # The fault-tolerant estimate replaces the raw generator-speed sensor while it is valid.
            self.using_estimates[:] = refs.valid  # in place, as below: the array is the controller's own
            if refs.power_ref is not None:
                self.power_ref = np.where(refs.valid, refs.power_ref, self.power_ref)
        else:
            self.using_estimates[:] = False
        return fresh

    def step(self, k: int, omega_g_m: np.ndarray, p_g_m: np.ndarray, refs: TurbineRefs | None) -> None:
        """Compute τ_g,r and β_ref for tick k from the turbine's own sensors and fresh references."""
        p = self.p
        omega_g = omega_g_m
        fresh = self._take(k, refs)
        if fresh and self._fast is None:  # the kernel below makes this choice row by row
            omega_g = np.where(refs.valid, refs.omega_g, omega_g_m)
        if self._fast is not None:  # the same operations, row by row, into the controller's own arrays
            # (written in place: the plant's frame and truth copy what they hand on, and nothing else keeps them)
            power_ref = np.ascontiguousarray(self.power_ref, dtype=float)
            estimate = refs.omega_g if fresh else omega_g_m
            self._fast.control(
                omega_g_m, self.using_estimates, estimate, p_g_m, power_ref, self.zone, self.integrator,
                self.beta_ref, self.tau_g_ref, self._constants,
            )  # fmt: skip
            return
        # Zone logic with the previous zone held (unit delay).
        to_region3 = (p_g_m >= self.power_ref) | (omega_g >= p.omega_nom)
        stay_region3 = omega_g >= p.omega_nom - p.omega_delta
        region3 = np.where(self.zone, stay_region3, to_region3)  # zone (0 or 1) as the condition
        self.zone = region3.view(np.int8)
        # Region-3 PI on the generator speed error, integrator and output saturated to the pitch range (clipped
        # in place: the same min(max(·, lo), hi), without temporaries).
        error = omega_g - p.omega_nom
        lo, hi = p.pitch_min_deg, p.pitch_max_deg
        integrator = self.integrator + p.dt * error
        self.integrator = np.minimum(np.maximum(integrator, lo, out=integrator), hi, out=integrator)
        beta_pi = p.K_p * error + p.K_i * self.integrator
        np.minimum(np.maximum(beta_pi, lo, out=beta_pi), hi, out=beta_pi)
        self.beta_ref = np.where(region3, beta_pi, 0.0)
        safe_omega = np.maximum(omega_g, 1.0)  # the constant-power law must not divide by a failed sensor's 0
        tau_region3 = self.power_ref / (p.eta_gc * safe_omega)
        tau_region2 = p.k_opt * omega_g * omega_g
        self.tau_g_ref = np.where(region3, tau_region3, tau_region2)

    def step_readings(
        self, k: int, y: np.ndarray, columns: tuple[int, int], refs: TurbineRefs | None, step: tuple, product
    ) -> None:
        """``step`` on the compiled backend from the readings ``y`` (n, sensors) and their (ω_g,m, P_g,m) ``columns``,
        the same numbers; in the same kernel call (``plant_sim.turbine.fast.control_inputs``) the plant's exact step
        inputs z = [x, τ_r, τ_g,r + Δτ, β_ref + β_f] from the new commands where ``step`` = (fill, x, τ_r, Δτ, β_f,
        z) asks, and with ``product`` = (the step matrix, x') one row's next state."""
        estimate = refs.omega_g if self._take(k, refs) else None
        self._fast.control_inputs(
            y, columns, self.using_estimates, estimate, np.ascontiguousarray(self.power_ref, dtype=float), self.zone,
            self.integrator, self.beta_ref, self.tau_g_ref, self._constants, step, product,
        )  # fmt: skip

    def step_readings_kept(self, k: int, y: np.ndarray, refs: TurbineRefs | None, kept, fill: bool, x, x_next) -> None:
        """``step_readings`` with the arguments that stay from tick to tick as one ``wwcore.kept.Kept`` ``kept``
        (``plant_sim.turbine.fast.control_inputs_kept``, built by the plant: the readings' columns, this controller's
        zone, integrator, β_ref, τ_g,r and constants, written in place and never replaced on the compiled backend,
        and the plant's step arguments); ``fill``, ``x`` and ``x_next`` (None: no product) as ``step_readings``'
        ``step`` and ``product``. The same numbers."""
        estimate = refs.omega_g if self._take(k, refs) else None
        self._fast.control_inputs_kept(
            y, self.using_estimates, estimate, np.ascontiguousarray(self.power_ref, dtype=float), kept, fill, x, x_next
        )
