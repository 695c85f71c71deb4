"""The plug-in roles of farm supervision, what they know and what they exchange.

A **farm detector** (registry ``service.plugins.FARM_DETECTORS``) is built as ``factory(context=FarmContext,
options=dict)`` and has ``step(sample: FarmSample) -> FarmDiagnosis``. A **farm controller** (``FARM_CONTROLLERS``)
is built the same way and has ``step(sample: FarmSample, faulty: np.ndarray) -> np.ndarray`` returning each
turbine's power reference (W); ``faulty`` (n, 3) is the detector's verdict per fault type (all False when
accommodation is off). Both run on 10 Hz farm samples only and see what a farm controller sees: the turbines'
SCADA means, their controller outputs, the met mast and the demand; never the plant's truth, the fault schedule
or the wind case or direction (the paper's detector estimates it: eqs. (1)–(2) or the mast's vane).

**Held turbines.** A sample may say that some turbines are ``held`` ((n,) bool; None, the default, when every
turbine is served): a sharded supervisor's coordinator has lost the shard that commands them, so the plant keeps
their last references (``FarmKind.hold_unserved``) and whatever the controller returns for them goes nowhere. A
controller that knows it treats them as fixed producers at the reference it returned them last and answers the
demand less theirs with the others (the ``dispatch``, ``docs/farm.md`` §2.5); one that ignores the field still runs,
and the supervisor sends the held rows' last references whatever it returns for them (``FarmSupervisor.decide``).
Their rows of the sample are their last summary, repeated.

A farm controller may also expose ``mode`` (n,) int8 (``wwcore.farm_frames.DISPATCH_MODES``: 3 holds the torque,
5 cancels the 3P torque without the hold), ``held_torque`` (n,) N m, ``pitch_trim`` (n, 3) deg and
``ripple_power`` (n,) complex W with ``ripple_rate`` (n,) rad/s; the supervisor forwards them to the turbines
(``wwcore.farm_frames.FarmRefs``), and takes a pitch trim it commanded off the next samples' pitch readings, as
the readings carry it (``service.farm.pitch_trim.TrimInReadings``), before the detector and the controller see them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from wwcore.backend import fast_module, resolve_backend
from wwcore.channels import SENSOR_INDEX, SENSORS
from wwcore.farm_frames import FarmFrame
from wwcore.layout import SEED001_DIRECTIONS_DEG, FarmLayout
from wwcore.scenario.farm import FARM_DT_S, FARM_FAULT_TYPES, ROTOR_DIAMETER_M, ROW_TOLERANCE_D, FarmPlant
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
    """One 10 Hz farm sample of ``farms`` farms (rows farm-major, N turbines each), in SI units."""

    j: int  # sample index; t = j·FARM_DT_S
    t: float  # s
    scada: np.ndarray  # (n, N_SENSORS) means of the last ten sensor readings
    zone: np.ndarray  # (n,) controller zone at the sample (0 region 2, 1 region 3 / derated)
    power_ref_used: np.ndarray  # (n,) W, the reference each turbine's controller followed
    mast: np.ndarray  # (farms,) m/s
    demand: np.ndarray  # (farms,) W
    mast_direction: np.ndarray | None = None  # (farms,) deg from north, the mast vane (None: the plant has none)
    held: np.ndarray | None = None  # (n,) bool, turbines no shard commands (module docstring; None: every one served)

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
            mast_direction=frame.mast_direction,
        )

    @property
    def farms(self) -> int:
        return len(self.mast)

    @property
    def turbines_per_farm(self) -> int:
        return len(self.scada) // len(self.mast)

    def untrimmed(self, pitch_trim: np.ndarray) -> FarmSample:
        """This sample with a per-blade pitch trim (n, 3) deg taken off the pitch readings: the blades as their
        actuators would hold them without it (what detectors and controllers are given), when ``pitch_trim`` is the
        trim the readings carry (``pitch_trim.TrimInReadings``)."""
        scada = self.scada.copy()
        scada[:, BETA] -= pitch_trim[:, :, None]
        return replace(self, scada=scada)

    def per_farm(self, values: np.ndarray) -> np.ndarray:
        """(n, …) → (farms, N, …)."""
        return values.reshape(self.farms, self.turbines_per_farm, *values.shape[1:])


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

    The layout is the site's: N = ``turbines`` per farm at ``positions`` (east, north in m) and the mast
    ``mast_distance_m`` upwind of the front row; *not* the wind direction. ``rows(direction)`` groups the turbines
    for any direction a detector has estimated (``groups_along_wind``: turbines within ``ROW_TOLERANCE_D`` rotor
    diameters of each other along the wind form a row), ``rows_of_case(case)`` for the paper's two wind cases on its
    3 × 3. The batch holds ``farms`` = n / N farms, rows farm-major. ``backend`` (``wwcore.backend``; None:
    ``$WINDWARDEN_STEP_BACKEND``, else numpy): with ``"numba"``, ``fast_aero`` is ``wwcore.aero_fast`` (else
    None), whose ``wind_from_torque`` the algorithms may use for ``wwcore.aero``'s (the same numbers), and ``fast``
    is ``service.farm.fast``, the compiled twin of their per-sample arithmetic.
    """

    def __init__(self, site: SiteInfo, n: int, params: TurbineParams = BENCHMARK, backend: str | None = None):
        if site.kind != "farm" or site.mast_distance_m is None:
            raise ValueError(f"a farm supervisor needs a farm's site (its layout and mast), not a {site.kind}'s")
        turbines = len(site.turbines)
        if len(site.positions_m) != turbines:
            raise ValueError(f"the site has {turbines} turbines but {len(site.positions_m)} positions")
        if n <= 0 or n % turbines:
            raise ValueError(f"{n} rows are not whole farms of {turbines} turbines")
        self.params = params
        self.n = n
        self.turbines = turbines
        self.farms = n // turbines
        self.dt = FARM_DT_S
        self.noise_convention = site.noise_convention
        self.sensor_sigma = np.array([site.sensor_sigma[c.name] for c in SENSORS])
        self.rotor_diameter_m = site.rotor_diameter_m or ROTOR_DIAMETER_M
        xy = np.array(site.positions_m, dtype=float).reshape(turbines, 2)
        self.layout = FarmLayout(xy[:, 0], xy[:, 1], self.rotor_diameter_m, source="site")
        self.mast_distance_m = site.mast_distance_m
        self.row_tolerance_m = ROW_TOLERANCE_D * self.rotor_diameter_m
        self.spacing_m = site.spacing_m
        self.paper_grid = is_seed001_grid(self.layout, site.spacing_m)
        # with the ``numba`` backend, ``wwcore.aero_fast``: its compiled wind inversion gives ``wwcore.aero``'s numbers
        self.backend = resolve_backend(backend)
        self.fast_aero = fast_module("wwcore.aero_fast") if self.backend == "numba" else None
        self.fast = fast_module("service.farm.fast") if self.backend == "numba" else None  # the algorithms' kernels

    def rows(self, direction_deg: float) -> list[tuple[int, ...]]:
        """Turbine numbers (1-based) grouped by distance along the wind from ``direction_deg``, front to back."""
        groups = self.layout.groups_along_wind(direction_deg, self.row_tolerance_m)
        return [tuple(i + 1 for i in g) for g in groups]

    def row_distances_m(self, direction_deg: float) -> list[float]:
        """Distance in m of each row of ``rows(direction_deg)`` from the front row along the wind (its first
        turbine's). On the paper's 3 × 3 in one of its wind cases, the closed form of ``FarmPlant.row_distances_m``
        (case 1: x; case 2: (x + y)/√2), which the rotation gives up to rounding."""
        for case, paper_direction in SEED001_DIRECTIONS_DEG.items():
            if self.paper_grid and direction_deg == paper_direction:
                plant = FarmPlant(spacing_m=self.spacing_m, mast_distance_m=self.mast_distance_m, wind_case=case)
                return plant.row_distances_m()
        s = self.layout.wind_frame(direction_deg).downwind
        return [float(s[g[0] - 1]) for g in self.rows(direction_deg)]


def is_seed001_grid(layout: FarmLayout, spacing_m: float | None) -> bool:
    """Whether ``layout`` is seed 001's 3 × 3 at ``spacing_m`` (turbines numbered row by row, rows southwards): the
    farm the paper's wind-case estimate (eqs. (1)–(2)) is written for."""
    if spacing_m is None or layout.n_turbines != 9:
        return False
    paper = FarmPlant(spacing_m=spacing_m).resolved_layout()
    return bool(np.allclose(layout.x, paper.x, atol=1e-3) and np.allclose(layout.y, paper.y, atol=1e-3))
