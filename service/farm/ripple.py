r"""A held turbine's 3P power ripple, and the phasors that let the rest of its farm cancel it [PROPOSED].

In the drive-train hold the turbine's converter takes the fault's 3P shaft torque off the shaft
(``plant_sim.farm.controller``, D-C4). The power the shaft swung back and forth then goes through the converter:
the turbine's electrical power carries a ripple at the planet-pass frequency ω_3 = 3 ω_g/N_g of about
η_gc ω_g J_g v̇ (0.3 MW at 12 m/s and 3 MW, 0.75 MW at rated speed), and so does the farm's output. The other
turbines of the farm can make its opposite with their converters: an equal share each, ≈ 40 kW, a torque of
≈ 0.3 kN m on the generator side, below 1 % of their working torque.

**Estimate** (per turbine whose ripple is cancelled, on each 10 Hz farm sample j at t_j, Δt = 0.1 s), from its
power readings P̄_g (each the mean of the ten readings at t_j − 0.1 … t_j − 0.01 s) and speed readings ω̄_g:

.. math::

    ω_3 = 3\bar ω_g/N_g,\qquad θ_j = θ_{j-1} + ω_3 Δt,\qquad
    c_j = \mathrm{LP}^3\bigl(2 (\bar P_{g,j} − \bar P_{g,j-1})\, e^{−jθ_j}\bigr),\qquad
    C_j = \frac{c_j\, e^{jθ_j}\, e^{jω_3 τ_b}}{D(ω_3)\,(1 − e^{−jω_3 Δt})}

The difference takes the mean power and its slow drift off (a ramp would leave a 3P-rate error after
demodulation); LP³ is three first-order low-passes of ``PHASOR_TIME_S`` each, which leave the demodulation's
image at 2ω_3 at ≈ 2 %; τ_b = 0.055 s is the centre of the block mean and D(ω) = ⅒ Σ_m cos(ω(m − 4.5)·0.01 s)
its gain (≈ 0.99). The ripple is then P_rip(t) ≈ Re{C_j e^{jω_3 (t − t_j)}} (``tests/farm/test_accommodation.py``
checks the closed form).

**Compensation**: each of the m free turbines of the farm (not held, derated or cancelling) is sent
C_i = −s C_j/m and ω_3 (``FarmRefs.ripple_power``, ``ripple_rate``); its converter adds Re{C_i e^{jω_3 (t − t_j)}}
to its power until the next reference (``plant_sim.farm.controller``). s = ``share`` is 1 by default (the whole
ripple); with s < 1 the farm's output keeps (1 − s) of it, which the dispatch's power loop still does not answer.
Nothing is sent until the estimate has settled, ``SETTLE_S`` after the turbine's cancellation began.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from service.farm.interfaces import OMEGA_G, P_G, FarmSample
from wwcore.scenario.farm import FARM_DT_S
from wwcore.turbine_params import TurbineParams

PHASOR_TIME_S = 0.4  # s, each of the low-passes of the demodulated ripple [PROPOSED]
PHASOR_STAGES = 3  # low-passes in a row [PROPOSED]
SETTLE_S = 1.5  # s after a turbine's cancellation begins before its estimate is sent [PROPOSED]
BLOCK_TICKS = 10  # readings per farm sample (``plant_sim.farm``: SCADA = mean of the last ten)


def block_mean_gain(omega: np.ndarray, dt: float) -> np.ndarray:
    """D(ω): the gain of the mean of ``BLOCK_TICKS`` readings Δt apart on e^{jωt}, taken at the block's centre."""
    offsets = (np.arange(BLOCK_TICKS) - 0.5 * (BLOCK_TICKS - 1)) * dt
    return np.cos(np.multiply.outer(omega, offsets)).mean(axis=-1)


class RippleCompensation:
    """The estimate and the compensating phasors for ``n`` turbine rows (farm-major, ``per_farm`` per farm)."""

    def __init__(self, params: TurbineParams, n: int, share: float = 1.0, per_farm: int = 9):
        self.p = params
        self.n = n
        self.per_farm = per_farm
        self.share = share  # s: the part of the ripple the free turbines are asked to cancel
        self.block_centre_s = 0.5 * (BLOCK_TICKS + 1) * params.dt  # s before t_j: the readings' mean time
        self._reset()

    def _reset(self) -> None:
        n = self.n
        self._estimating = False  # a step with sources since the last reset; else the state below is the reset's
        self._theta = np.zeros(n)  # rad, demodulation phase θ_j of the sources
        self._previous = np.full(n, np.nan)  # W, P̄_g,j−1 of the sources (NaN: not a source)
        self._stages = np.zeros((PHASOR_STAGES, n), dtype=complex)
        self._age = np.zeros(n)  # s since the row became a source
        self.ripple = np.zeros(n, dtype=complex)  # W, C_j of the sources (0 until settled)
        self.source_rate = np.zeros(n)  # rad/s, ω_3 of the sources' ripple (0 until settled)
        self.power = np.zeros(n, dtype=complex)  # W, the phasor each row is asked to add to its power
        self.rate = np.zeros(n)  # rad/s, its frequency

    def step(self, sample: FarmSample, sources: np.ndarray, free: np.ndarray) -> None:
        """Update from the sample: ``sources`` (n,) rows whose ripple is estimated, ``free`` (n,) rows that may
        compensate it."""
        if not sources.any():
            # after a reset nothing is left to clear (the test below would find nothing), so no numpy call
            if self._estimating and (self.power.any() or not np.isnan(self._previous).all()):
                self._reset()
            return
        self._estimating = True
        p, dt = self.p, FARM_DT_S
        power = sample.scada[:, P_G]
        omega_3 = 3.0 * sample.scada[:, OMEGA_G].mean(axis=1) / p.N_g
        starting = sources & np.isnan(self._previous)
        change = np.where(starting, 0.0, power - self._previous)
        self._previous = np.where(sources, power, np.nan)
        self._theta = np.where(starting, 0.0, self._theta + omega_3 * dt)
        self._stages[:, starting] = 0.0
        self._age = np.where(sources, np.where(starting, 0.0, self._age + dt), 0.0)
        gain = dt / PHASOR_TIME_S
        stage = 2.0 * change * np.exp(-1j * self._theta)
        for states in self._stages:
            states += (stage - states) * gain
            stage = states.copy()
        settled = sources & (self._age >= SETTLE_S - 1e-9)
        seen = block_mean_gain(omega_3, p.dt) * (1.0 - np.exp(-1j * omega_3 * dt))
        seen = np.where(np.abs(seen) > 1e-9, seen, 1.0)  # a stopped turbine has no 3P
        rotation = np.exp(1j * (self._theta + omega_3 * self.block_centre_s))
        self.ripple = np.where(settled, stage * rotation / seen, 0.0)
        self.source_rate = np.where(settled, omega_3, 0.0)
        self._share(self.source_rate, free & ~sources)

    def without_ripple(self, sample: FarmSample) -> FarmSample:
        """The sample with the 3P power its block of readings carries taken off P̄_g: the sources' ripple as last
        estimated, the others' compensation as last asked (Re{C e^{jω(Δt − τ_b)}} D(ω), C referred to the previous
        sample). What the farm controller reads: the ripple is this module's to cancel, not its power loop's."""
        if not self._estimating:  # no ripple estimated, no compensation asked: nothing to take off
            return sample
        phasor, rate = self.ripple + self.power, self.source_rate + self.rate
        if not phasor.any():
            return sample
        content = (phasor * np.exp(1j * rate * (FARM_DT_S - self.block_centre_s))).real
        scada = sample.scada.copy()
        scada[:, P_G] -= content * block_mean_gain(rate, self.p.dt)
        return replace(sample, scada=scada)

    def _share(self, omega_3: np.ndarray, free: np.ndarray) -> None:
        """Each free turbine of a farm takes an equal share of the opposite of its farm's ripple. One turbine
        per farm is the rule (one fault reported at a time); with several, the free ones cancel the largest."""
        farms = self.n // self.per_farm
        ripple = self.ripple.reshape(farms, self.per_farm)
        free = free.reshape(farms, self.per_farm)
        largest = np.argmax(np.abs(ripple), axis=1)
        rows = np.arange(farms)
        share = -self.share * ripple[rows, largest] / np.maximum(free.sum(axis=1), 1)
        self.power = np.where(free, share[:, None], 0.0).reshape(-1)
        rate = omega_3.reshape(farms, self.per_farm)[rows, largest]
        self.rate = np.where(free & (share != 0.0)[:, None], rate[:, None], 0.0).reshape(-1)
