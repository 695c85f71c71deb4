"""The messages between the hydrostatic plant and its supervisor, declared once (the step contract's payloads).

``HydroFrame`` is what ``plant.measure()`` returns at tick k; ``HydroRefs`` is what ``supervisor.step(frame)``
returns and ``plant.control(refs)`` consumes at tick k+1. Arrays are over the batch of n turbines.
Column orders are ``wwcore.hydro_params.Y_NAMES``, ``U_NAMES`` and ``FAULT_TARGETS``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wwcore.hydro_params import NOMINAL


@dataclass(frozen=True)
class HydroFrame:
    """Sensor readings y_k (with noise) and the commands u_{k−1} the actuators received during [t_{k−1}, t_k)."""

    t: float  # s, simulation time of tick k
    k: int  # tick index
    y: np.ndarray  # (n, 5) [ω_r rad/s, ω_g rad/s, T_g N m, x̃_p –, x̃_M –], measured
    u: np.ndarray  # (n, 3) [u_p –, u_M –, T_g,d N m], commands sent (after any correction of eq. (36))


@dataclass(frozen=True)
class HydroRefs:
    """The supervisor's output for the turbine controller (and the estimates, for display)."""

    t: float  # s, time of the frame these refs were computed from
    k: int  # tick index of that frame
    correction: np.ndarray  # (n, 2) f̂_a,filt for [u_p, u_M], to subtract from the commands, eq. (36)
    apply: np.ndarray  # (n,) bool: the correction is valid and compensation is on
    f_hat: np.ndarray  # (n, 2) unfiltered reconstruction, eq. (35)
    x_hat: np.ndarray  # (n, 6) observer states [ω_r, ω_g, Δp, T_g, x̃_p, x̃_M]
    flagged: np.ndarray  # (n, 2) bool: the detector flags [u_p, u_M] as faulty


HYDRO_REFS_LIMITS = {"correction": (-NOMINAL.stroke_max, NOMINAL.stroke_max, ("apply", "==", True))}
"""What the plant takes (``wwcore.wire.WireField.limits``): a correction of the displacement commands (normalised
stroke) beyond ± the stroke limit means nothing; it holds on the rows whose correction is to be applied."""
