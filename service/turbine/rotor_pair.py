"""Whether a generator-speed explanation leaves out a rotor-speed fault: the sequential tests on the rotor-speed
sensors that decide, while an isolation waits, whether an explanation naming no rotor-speed sensor is flagged as it
is, waits, or takes a rotor-speed sensor in (``fdi``; docs/turbine.md, "The rotor-speed pair's sequential test" and
"Against one encoder"; docs/decisions.md N-16, N-22, N-23).

A rotor-speed gain of a few percent beside a generator-speed fault shows in the rotor-speed readings from its first
tick, while the UIOs see it only as their states drift from it. The sums live in ``arbitration.GeneratorArbiter``
(from the isolation's start); this module reads them as Wald's sequential tests:

* **Against one encoder** (an explanation naming exactly one generator-speed sensor): each rotor-speed sensor
  against the generator-speed sensor the explanation leaves trusted, through the gear, e_s = (y_rs − y_gk/N_g)/σ_e,
  white N(0, 1) on the plant at every wind, in the pair's learnt spread ŝ. Λ_s = m |Σe_s| − k m²/2 (m =
  ``rotor_pair_shift`` σ, the sign that fits); join at max Λ_s ≥ ln(4/α_iso) (four alternatives: Ville over every
  look), decide alone once every Λ_s ≤ −ln(1/α_confirm) (a bias of the design size gets there with probability
  ≤ α_confirm); the sensor with the larger Λ_s is the one that joins.
* **The pair** (an explanation naming both generator-speed sensors): Λ = m_d |Σd| − k m_d²/2 on the pair's difference
  d = (y_r1 − y_r2)/(σ_d ŝ) in its learnt spread, m_d = ``bias_shift``/√2 σ_d, join at ln(2/α_iso), the same lower
  level (N-16); the UIOs' statistics then choose which rotor-speed sensor joins.
* **One look** (an explanation naming a frozen sensor, decided on the frozen test's tick): the pair's z beyond the
  isolation's two-sided level in the pair's learnt spread (N-22) does not join a sensor by itself; it hands the
  decision to the sequential test above, which the explanation then waits on as any other (a healthy pair joins
  where both pass: about α_iso × 0.02–0.05 a look against one encoder, × 0.04–0.13 for the pair, instead of α_iso).
"""

from __future__ import annotations

import math

import numpy as np

from service.turbine.arbitration import GeneratorArbiter
from service.turbine.bank import GENERATOR
from service.turbine.bias_test import ROTOR, RotorBiasTest
from service.turbine.fdi_settings import FDISettings
from wwcore.channels import SPEED_SENSORS

_ROTOR_BIT = tuple(1 << r for r in ROTOR)
_ROTOR_BITS = sum(_ROTOR_BIT)
_GENERATOR_BIT = tuple(1 << SPEED_SENSORS.index(g) for g in GENERATOR)


class RotorPairTest:
    """The sequential tests of the rotor-speed sensors for the isolations of n turbines (module docstring), on the
    sums of ``arbiter``; ``bias`` (or None) holds the pair's learnt spread ŝ; α_iso = ``iso``, α_confirm =
    ``confirm``; ``patience``: the most ticks the tests may hold an isolation open."""

    def __init__(
        self,
        arbiter: GeneratorArbiter,
        settings: FDISettings,
        iso: float,
        confirm: float,
        bias: RotorBiasTest | None,
        patience: int,
    ):
        self.arbiter = arbiter
        self.bias = bias
        # the pair's test: "both healthy" against "one biased by the bias test's smallest design size" (``bias_shift``
        # σ on one sensor, m_d σ_d of the pair's difference)
        rotor_sigma = math.sqrt(arbiter.rotor_variance) / arbiter.gear_ratio  # σ_r1, rad/s
        self.shift = settings.bias_shift * rotor_sigma / arbiter.parity_sigma
        # a rotor-speed sensor joins once Λ ≥ ln(2/α_iso): ½(e^Λ⁺ + e^Λ⁻) is a martingale of mean 1 on a healthy
        # pair, so it ever gets there with probability ≤ α_iso however many ticks are looked at (Ville)
        self.join_level = math.log(2.0 / iso)
        # the pair is judged healthy once Λ ≤ −ln(1/α_confirm): a bias of at least the design size ever gets there
        # with probability ≤ α_confirm (e^−Λ is a martingale under it), larger ones far less often
        self.healthy_level = -math.log(1.0 / confirm)
        self.patience = patience
        # against one encoder: twice the pair's information per tick, spent on a smaller design bias
        # (``rotor_pair_shift``); four alternatives (two sensors, two signs) share α_iso
        self.encoder_shift = settings.rotor_pair_shift
        self.encoder_join_level = math.log(2.0 * len(ROTOR) / iso)

    def _spread(self, row: int) -> float:
        """ŝ of ``row``: the rotor-speed bias test's learnt spread of the pair's difference (1 without the test)."""
        return float(self.bias.spread.scale[row]) if self.bias is not None else 1.0

    def verdict(self, row: int, explanation: int = 0) -> int:
        """The sequential test on ``row`` since its isolation started: +1 when a rotor-speed sensor is biased (a
        healthy pair gets there with probability ≤ α_iso over any number of looks), −1 when both are healthy (a bias
        of the design size gets there with probability ≤ α_confirm), 0 while the evidence is between the two. Where
        the ``explanation`` (bitmask) names one generator-speed sensor, against the other one
        (``encoder_log_ratios``); elsewhere the pair's difference (``arbitration``: Λ = m_d |Σd| − k m_d²/2)."""
        return self._decide(row, self.encoder_log_ratios(row, explanation))

    def _decide(self, row: int, ratios: np.ndarray | None) -> int:
        """``verdict`` from the tests against one encoder's Λ_s (``ratios``; None: the pair's test)."""
        if ratios is not None:
            evidence, join = float(ratios.max()), self.encoder_join_level
        else:
            evidence, join = float(self.arbiter.rotor_log_ratio(self.shift, row, self._spread(row))), self.join_level
        if evidence >= join:
            return 1
        return -1 if evidence <= self.healthy_level else 0

    def encoder_log_ratios(self, row: int, explanation: int) -> np.ndarray | None:
        """Λ_s (2,) of "rotor-speed sensor s biased by ±``rotor_pair_shift`` σ" against "both healthy", each
        rotor-speed sensor against the generator-speed sensor the ``explanation`` leaves trusted through the gear,
        in the pair's learnt spread ŝ (``arbitration.rotor_sensor_log_ratios``); None unless the explanation names
        exactly one generator-speed sensor."""
        generator = explanation & sum(_GENERATOR_BIT)
        if generator not in _GENERATOR_BIT:
            return None
        encoder = 1 - _GENERATOR_BIT.index(generator)  # the generator-speed sensor left trusted
        return self.arbiter.rotor_sensor_log_ratios(self.encoder_shift, row, encoder, self._spread(row))

    def disagrees(self, row: int) -> bool:
        """The frozen sensor's one look at the rotor-speed pair on ``row``: z > z_iso ŝ (√ of the learnt second
        moment, clipped to [1, ``max_noise_scale``]), so noisier sensors or a calibration offset within tolerance pass
        no more often than α_iso."""
        return bool(self.arbiter.rotor_z[row] > self.arbiter.parity_level * self._spread(row))

    def with_rotor(
        self,
        row: int,
        explanation: int,
        own: np.ndarray,
        observer_of_mask: np.ndarray,
        frozen: int = 0,
        disagreed: bool = False,
    ) -> int:
        """The ``explanation`` with a rotor-speed sensor added where it names none and the sequential test says one
        is biased (``verdict`` +1); for an explanation naming a ``frozen`` sensor only where, besides, the one look
        found the pair disagreeing (``disagreed`` on an earlier tick of the isolation, or ``disagrees`` now): a
        healthy pair passes the look with probability α_iso and then the test's level in a few hundredths of
        those. The test against one encoder names the sensor; otherwise, of the two, the one whose explanation's
        own observer (``observer_of_mask``) has the smaller statistic (``own``, at the isolation level)."""
        if explanation & _ROTOR_BITS:
            return explanation
        if explanation & frozen and not (disagreed or self.disagrees(row)):
            return explanation
        ratios = self.encoder_log_ratios(row, explanation)
        if self._decide(row, ratios) <= 0:
            return explanation
        candidates = [explanation | bit for bit in _ROTOR_BIT if observer_of_mask[explanation | bit] >= 0]
        if ratios is not None:
            named = explanation | _ROTOR_BIT[int(ratios.argmax())]
            candidates = [named] if named in candidates else candidates
        if not candidates:
            return explanation
        return int(min(candidates, key=lambda m: own[observer_of_mask[m]]))
