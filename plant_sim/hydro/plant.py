"""The hydrostatic wind turbine as a batch plant following ``wwcore.stepping.Plant``.

n independent turbines (one per Monte Carlo run), each with its own random streams for wind and noise. One
tick (dt = 10 ms):

* ``measure()``: y_k = C x_k (1 + ε_k), ε uniform in ±noise_pct %, plus the commands of tick k−1;
* ``control(refs)``: the baseline controller (``controller.py``) computes u_k from y_k and, when ``refs``
  carries a valid correction, sends u_corr = u − f̂_a,filt (eq. 36);
* ``advance()``: the actuators receive ũ = u_corr + f_a (eq. 38), clamped to the stroke range, and eq. (4) is
  integrated from t_k to t_{k+1} with the inputs and the wind held.

Integrator: classical RK4 with step dt = 10 ms (``substeps`` = 1). Although C_H is small, the pressure state is
not stiff with these parameters: the fastest eigenvalue of eq. (4) is the generator-torque lag −1/τ_g = −50 s⁻¹
(h|λ| = 0.5, inside RK4's real-axis stability limit 2.78), the displacement lags are −10 s⁻¹, and the
generator–pressure mode sits at 2.3–3.5 rad/s with ζ ≈ 0.1 (``HydroParams.hydraulic_mode``; hω = 0.035, RK4's
phase and amplitude errors ≈ (hω)⁵/120 per step, negligible). ``tests/hydro/test_plant.py`` checks the result
against a 10× finer step.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from plant_sim.hydro.controller import BaselineController
from plant_sim.hydro.wind import CHUNK_TICKS, HydroWind
from wwcore.events import Event, EventType
from wwcore.hydro_frames import HydroFrame, HydroRefs
from wwcore.hydro_model import aero_torque, derivative, equilibrium
from wwcore.hydro_params import FAULT_TARGETS, NOMINAL, HydroParams
from wwcore.scenario.faults import FaultSpec
from wwcore.scenario.hydro import HydroPlant
from wwcore.scenario.wind import WindSpec

_OUTPUT_STATES = (0, 1, 3, 4, 5)  # y = C x picks ω_r, ω_g, T_g, x̃_p, x̃_M


def _child(seed: np.random.SeedSequence, index: int) -> np.random.SeedSequence:
    """The ``index``-th child of ``seed``, the same every time (unlike ``seed.spawn``)."""
    return np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, index), pool_size=seed.pool_size)


class HydroTurbineBatch:
    """n hydrostatic turbines under one scenario (same faults), independent wind and noise per run."""

    def __init__(
        self,
        spec: HydroPlant,
        wind: WindSpec,
        faults: list[FaultSpec],
        seeds: list[np.random.SeedSequence],
        run_ids: list[int] | None = None,
        params: HydroParams = NOMINAL,
        substeps: int = 1,
        fault_mask: np.ndarray | None = None,
    ):
        """``seeds``: one ``SeedSequence`` per turbine (wind and noise derive from it, so twins built from the same
        seeds see the same wind and noise). ``fault_mask`` (n,) bool: the turbines the faults act on (default
        all), so faulty and fault-free twins can share one batch."""
        self.spec = spec
        self.nominal = replace(params, stroke_max=spec.stroke_max)  # what the controller knows
        self.true = self.nominal.with_uncertainty(spec.leak_factor)  # what the plant is, eq. (16)
        self.dt = self.nominal.dt
        self.n = len(seeds)
        self.k = 0
        self.run_ids = list(range(self.n)) if run_ids is None else list(run_ids)
        self.substeps = substeps
        self.fault_mask = np.ones(self.n, dtype=bool) if fault_mask is None else np.asarray(fault_mask, dtype=bool)
        # wind and noise streams derived without spawn(), which would advance the caller's SeedSequence and
        # give a twin plant built from the same seeds different numbers
        self.wind = HydroWind(wind, self.dt, [np.random.default_rng(_child(s, 0)) for s in seeds])
        self._noise_rngs = [np.random.default_rng(_child(s, 1)) for s in seeds]
        self._noise = np.zeros((self.n, 0, 5))
        self._noise_pos = 0
        self.faults: list[FaultSpec] = list(faults)
        self._active: set[str] = set()
        self._cleared: set[str] = set()
        self._events: list[Event] = []
        eq = equilibrium(self.wind.speed(0.0), self.nominal, spec.delta_cq)
        self.x = eq.x.copy()
        self.controller = BaselineController(self.nominal, self.n, eq.pi_integral)
        self.u_sent = eq.u.copy()  # commands of the previous tick
        self.u_nominal = eq.u.copy()
        self.f = np.zeros(2)
        self.u_applied = eq.u.copy()
        self._y = self._measure_now()

    # -- time ------------------------------------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self.k * self.dt

    # -- faults ----------------------------------------------------------------------------------------------
    def inject(self, fault: FaultSpec) -> None:
        """Add a fault at run time (the API's injection); it becomes active at its ``start_s``."""
        if fault.label in {f.label for f in self.faults}:
            raise ValueError(f"a fault labelled {fault.label!r} exists already")
        self.faults.append(fault)

    def clear(self, label: str) -> None:
        """End the fault ``label`` now (it is cleared at the next tick)."""
        if label not in {f.label for f in self.faults}:
            raise KeyError(f"no fault labelled {label!r}")
        self._cleared.add(label)

    def fault_offsets(self, t: float) -> np.ndarray:
        """f_a(t) = [f_a,1 on u_p, f_a,2 on u_M], the sum of the active offsets (ramps included)."""
        f = np.zeros(2)
        for fault in self.faults:
            if fault.label in self._cleared:
                continue
            f[FAULT_TARGETS.index(fault.target)] += float(fault.value or 0.0) * fault.intensity(t)
        return f

    def _update_fault_events(self, t: float) -> None:
        for fault in self.faults:
            on = fault.label not in self._cleared and fault.intensity(t) > 0.0
            was = fault.label in self._active
            if on == was:
                continue
            kind = EventType.FAULT_INJECTED if on else EventType.FAULT_CLEARED
            (self._active.add if on else self._active.discard)(fault.label)
            detail = {"label": fault.label, "value": fault.value, "kind": fault.kind.value}
            self._events += [
                Event(t, kind, 1, fault.target, run, detail)
                for run, hit in zip(self.run_ids, self.fault_mask, strict=True)
                if hit
            ]

    # -- step contract ---------------------------------------------------------------------------------------
    def _next_noise(self) -> np.ndarray:
        if self._noise_pos >= self._noise.shape[1]:
            a = self.spec.noise_pct / 100.0
            self._noise = np.stack([rng.uniform(-a, a, (CHUNK_TICKS, 5)) for rng in self._noise_rngs])
            self._noise_pos = 0
        eps = self._noise[:, self._noise_pos]
        self._noise_pos += 1
        return eps

    def _measure_now(self) -> np.ndarray:
        return self.x[:, _OUTPUT_STATES] * (1.0 + self._next_noise())

    def measure(self) -> HydroFrame:
        """y_k (noisy) and the commands u_{k−1} the actuators received over the last tick."""
        return HydroFrame(t=self.t, k=self.k, y=self._y.copy(), u=self.u_sent.copy())

    def control(self, refs: HydroRefs | None) -> None:
        """Compute u_k from y_k; apply the supervisor's correction (36) when ``refs`` carries a valid one.

        With ``refs`` None (no or stale references) the controller keeps the last valid correction.
        """
        if refs is not None:
            self.controller.set_correction(refs.correction, refs.apply)
        self.u_sent, self.u_nominal = self.controller.step(self._y)

    def advance(self) -> None:
        """Integrate eq. (4) from t_k to t_{k+1} (RK4, inputs and wind held), then sample y_{k+1}."""
        t = self.t
        self._update_fault_events(t)
        self.f = self.fault_offsets(t)
        p = self.true
        u = self.u_sent.copy()
        # (38) ũ = u_corr + f_a, within the mechanical stroke range
        u[:, :2] = np.clip(u[:, :2] + self.f * self.fault_mask[:, None], p.stroke_min, p.stroke_max)
        self.u_applied = u
        v = self.wind.speed(t)
        h = self.dt / self.substeps

        def rhs(x: np.ndarray) -> np.ndarray:
            return derivative(x, u, aero_torque(x[:, 0], v, p, self.spec.delta_cq), p)

        x = self.x
        for _ in range(self.substeps):
            k1 = rhs(x)
            k2 = rhs(x + 0.5 * h * k1)
            k3 = rhs(x + 0.5 * h * k2)
            k4 = rhs(x + h * k3)
            x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        self.x = x
        self.wind.advance(t)
        self.k += 1
        self._y = self._measure_now()

    def truth(self) -> dict[str, np.ndarray]:
        """Ground truth for scoring and display only (the supervisor never reads it)."""
        v = self.wind.speed(self.t)
        return {
            "t": np.array(self.t),
            "x": self.x.copy(),
            "f": self.fault_offsets(self.t) * self.fault_mask[:, None],
            "v": v,
            "T_r": aero_torque(self.x[:, 0], v, self.true, self.spec.delta_cq),
            "u_applied": self.u_applied.copy(),
            "u_nominal": self.u_nominal.copy(),
            "P_g": self.x[:, 1] * self.x[:, 3],
        }

    def drain_events(self) -> list[Event]:
        out, self._events = self._events, []
        return out
