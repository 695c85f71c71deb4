"""The plug-in roles of farm supervision, what they know and what they exchange.

A **farm detector** (registry ``service.plugins.FARM_DETECTORS``) is built as ``factory(context=FarmContext,
options=dict)`` and has ``step(sample: FarmSample) -> FarmDiagnosis``. A **farm controller** (``FARM_CONTROLLERS``)
is built the same way and has ``step(sample: FarmSample, faulty: np.ndarray) -> np.ndarray`` returning each
turbine's power reference (W); ``faulty`` (n, 3) is the detector's verdict per fault type (all False when
accommodation is off). Both run on 10 Hz farm samples only and see what a farm controller sees: the turbines'
SCADA means, their controller outputs, the met mast and the demand; never the plant's truth, the fault schedule
or the wind case (the paper's detector estimates it, eqs. (1)–(2)).

A farm controller may also expose ``mode`` (n,) int8 (``wwcore.farm_frames.DISPATCH_MODES``: 3 holds the torque,
5 cancels the 3P torque without the hold), ``held_torque`` (n,) N m, ``pitch_trim`` (n, 3) deg and
``ripple_power`` (n,) complex W with ``ripple_rate`` (n,) rad/s; the supervisor forwards them to the turbines
(``wwcore.farm_frames.FarmRefs``), and takes a pitch trim it commanded off the next samples' pitch readings
before the detector and the controller see them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from wwcore.channels import SENSOR_INDEX, SENSORS
from wwcore.farm_frames import FarmFrame
from wwcore.scenario.farm import FARM_DT_S, FARM_FAULT_TYPES, N_TURBINES, FarmPlant
from wwcore.site import SiteInfo
from wwcore.turbine_params import BENCHMARK, TurbineParams

OMEGA_R = np.array([SENSOR_INDEX["omega_r_m1"], SENSOR_INDEX["omega_r_m2"]])
OMEGA_G = np.array([SENSOR_INDEX["omega_g_m1"], SENSOR_INDEX["omega_g_m2"]])
BETA = np.array([[SENSOR_INDEX[f"beta_{i}_m{j}"] for j in (1, 2)] for i in (1, 2, 3)])  # (blade, sensor)
TAU_G = SENSOR_INDEX["tau_g_m"]
P_G = SENSOR_INDEX["p_g_m"]
V_HUB = SENSOR_INDEX["v_hub_m"]
N_TYPES = len(FARM_FAULT_TYPES)


@dataclass
class FarmSample:
    """One 10 Hz farm sample of ``farms`` farms (rows farm-major, 9 turbines each), in SI units."""

    j: int  # sample index; t = j·FARM_DT_S
    t: float  # s
    scada: np.ndarray  # (n, N_SENSORS) means of the last ten sensor readings
    zone: np.ndarray  # (n,) controller zone at the sample (0 region 2, 1 region 3 / derated)
    power_ref_used: np.ndarray  # (n,) W, the reference each turbine's controller followed
    mast: np.ndarray  # (farms,) m/s
    demand: np.ndarray  # (farms,) W

    @classmethod
    def from_frame(cls, frame: FarmFrame, dt: float) -> FarmSample:
        j = round((frame.k + 1) * dt / FARM_DT_S)
        return cls(
            j=j,
            t=j * FARM_DT_S,
            scada=frame.scada,
            zone=frame.turbines.zone,
            power_ref_used=frame.power_ref_used,
            mast=frame.mast,
            demand=frame.demand,
        )

    @property
    def farms(self) -> int:
        return len(self.mast)

    def untrimmed(self, pitch_trim: np.ndarray) -> FarmSample:
        """This sample with a commanded per-blade pitch trim (n, 3) deg taken off the pitch readings: the blades as
        their actuators would hold them without it (what detectors and controllers are given)."""
        scada = self.scada.copy()
        scada[:, BETA] -= pitch_trim[:, :, None]
        return replace(self, scada=scada)

    def per_farm(self, values: np.ndarray) -> np.ndarray:
        """(n, …) → (farms, 9, …)."""
        return values.reshape(self.farms, N_TURBINES, *values.shape[1:])


@dataclass
class FarmDiagnosis:
    """A farm detector's verdict: which turbine has which of the paper's three faults, and the test margins."""

    faulty: np.ndarray  # (n, 3) bool, columns FARM_FAULT_TYPES (debris, pitch_misalignment, drivetrain)
    statistics: np.ndarray  # (n, 3) the test statistic of each fault type (CUSUM g or amplitude)
    thresholds: np.ndarray  # (n, 3) the alarm threshold of each statistic (NaN where a test is not run)
    extra: dict[str, np.ndarray] = field(default_factory=dict)  # detector-specific signals for display

    @property
    def margins(self) -> np.ndarray:
        """statistic / threshold; > 1 trips."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.statistics / self.thresholds


def empty_diagnosis(n: int) -> FarmDiagnosis:
    return FarmDiagnosis(np.zeros((n, N_TYPES), dtype=bool), np.zeros((n, N_TYPES)), np.full((n, N_TYPES), np.nan))


class FarmContext:
    """What every farm algorithm may know: the turbine's parameters, the sensor noise, the layout, the batch size.

    The layout is the grid and the mast position, *not* the wind case: ``rows(case)`` gives the rows of either
    case for a detector that has estimated it.
    """

    def __init__(self, site: SiteInfo, n: int, params: TurbineParams = BENCHMARK):
        if site.kind != "farm" or site.spacing_m is None or site.mast_distance_m is None:
            raise ValueError(f"a farm supervisor needs a farm's site (grid spacing and mast), not a {site.kind}'s")
        self.params = params
        self.n = n
        self.farms = n // N_TURBINES
        self.dt = FARM_DT_S
        self.noise_convention = site.noise_convention
        self.sensor_sigma = np.array([site.sensor_sigma[c.name] for c in SENSORS])
        self._geometry = {
            case: FarmPlant(spacing_m=site.spacing_m, mast_distance_m=site.mast_distance_m, wind_case=case)
            for case in (1, 2)
        }
        self.mast_distance_m = site.mast_distance_m

    def rows(self, case: int) -> list[tuple[int, ...]]:
        return self._geometry[case].rows()

    def row_distances_m(self, case: int) -> list[float]:
        return self._geometry[case].row_distances_m()
