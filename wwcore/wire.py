"""The wire contract, declared once: message schemas with units, versions, and the codec; the key expressions
they travel on are in ``wwcore.keys``.

Pure (numpy and the standard library only): the Zenoh edges in ``windwarden.live`` and ``api`` put on the wire
what this module encodes and refuse what it cannot decode. Nothing here opens a socket.

Key-expression tree (``<farm>`` is one chunk, ``<sender>`` the supervisor's name: ``supervisor``, or a shard's)::

    windwarden/<farm>/sensors                plant → supervisor    frame   per tick     may drop (realtime)
    windwarden/<farm>/refs/<sender>          supervisor → plant    frame   per tick     reliable, blocking
    windwarden/<farm>/truth                  plant → display       frame   decimated    may drop; never read by
                                                                                         the supervisor
    windwarden/<farm>/metmast                plant → supervisor    binary  per tick     may drop (farm kind)
    windwarden/<farm>/plant/status           plant → anyone        JSON    2 Hz + queryable (run status)
    windwarden/<farm>/plant/run              queryable             JSON    what the supervisor may know of the run
    windwarden/<farm>/plant/faults           queryable             JSON    inject / clear / list faults
    windwarden/<farm>/plant/events           plant → all           JSON    the plant's events; reliable, blocking
    windwarden/<farm>/supervisor/status      supervisor → anyone   JSON    2 Hz + queryable (per-turbine status)
    windwarden/<farm>/supervisor/events      supervisor → all      JSON    the supervisor's events; reliable, blocking
    windwarden/<farm>/alive/<process>        liveliness tokens (plant, supervisor, api)

A sharded supervisor (``windwarden supervise --turbines``, ``windwarden coordinate``) adds::

    windwarden/<farm>/summary/<name>         shard → coordinator   frame   10 Hz farm samples   reliable, blocking
    windwarden/<farm>/dispatch/<name>        coordinator → shard   frame   10 Hz (farm.refs)    reliable, blocking
    windwarden/<farm>/shard/<name>/status    shard → coordinator   JSON    2 Hz (run, turbines, ready)

Each stream has one publishing process, so the router's access control (``windwarden.live.access``) can say who
may put where: plant and supervisor events have a key each, and readers subscribe to ``windwarden/<farm>/*/events``.

Binary messages (the per-tick streams) are frames: a 4-byte header ``b"WW"``, schema code (u8), schema version (u8),
then 1 to ``MAX_FRAME_ROWS`` packed little-endian records (one per turbine, each carrying its turbine number and
tick) whose layout is the schema's fields in order; the row count is the length over the record size. One frame per
tick per sender: the plant's sensors of all its turbines, a supervisor's refs of all the turbines it owns (a single
turbine is a frame of one row, byte for byte what a one-record message is). ``frame_problem`` says why the rows of a
frame cannot be one tick's (two ticks, a turbine twice). Floats travel as float64, so a
lockstep run sees bit for bit what the batch loop sees. JSON messages (the control plane, a few per second) are
``{"schema": name, "v": version, "body": {...}}``. A message with an unknown schema or version, a bad length or a
bad body raises ``WireError``; receivers drop it and count it (``DropCounter``), never crash.

A message that decodes is not yet trusted. The refs fields a plant acts on carry their physical range
(``WireField.limits``, in the field's unit, declared once per plant kind next to its frames: ``*_REFS_LIMITS`` in
``wwcore.turbine_frames``, ``hydro_frames``, ``farm_frames``); ``MessageSchema.refusal`` says whether a refs record
is finite and inside them, and the plant refuses it otherwise. Sensor frames carry the plant's run identity (``run``),
so the supervisor can tell a new run from an old or replayed frame.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from functools import cached_property
from typing import Any

import numpy as np

from wwcore.channels import N_SENSORS, SENSOR_NAMES, SENSORS
from wwcore.farm_frames import FARM_REFS_LIMITS
from wwcore.hydro_frames import HYDRO_REFS_LIMITS
from wwcore.hydro_params import FAULT_TARGETS, U_NAMES, X_NAMES, Y_NAMES, Y_UNITS
from wwcore.scenario.farm import FARM_FAULT_TYPES
from wwcore.turbine_frames import POWER_MAX, TURBINE_REFS_LIMITS
from wwcore.wire_check import DropCounter as DropCounter  # exported with the codec: every receiver counts its drops
from wwcore.wire_check import RangeCheck, with_limits

MAGIC = b"WW"
MAX_FRAME_ROWS = 1024  # rows of one frame: more turbines than any farm has; a longer message is refused unread
HEADER = np.dtype([("magic", "S2"), ("code", "u1"), ("version", "u1")])
MAX_JSON_BYTES = 256 * 1024  # a control-plane message larger than this is refused unparsed
MAST_WIND_MAX = 100.0  # m/s: beyond any wind a met mast reads
FARM_DEMAND_MAX = 1e10  # W: a farm's demand (150 turbines of 4.8 MW are 0.72 GW)


class WireError(ValueError):
    """A message that cannot be decoded. ``reason`` is one of the ``DropReason`` values."""

    def __init__(self, reason: str, message: str):
        self.reason = reason
        super().__init__(message)


class DropReason(StrEnum):
    BAD_MAGIC = "bad_magic"
    UNKNOWN_SCHEMA = "unknown_schema"
    BAD_VERSION = "bad_version"
    BAD_LENGTH = "bad_length"
    BAD_BODY = "bad_body"
    INCOMPLETE = "incomplete"  # a tick whose rows never all arrived (multi-turbine plants)
    MIXED_TICKS = "mixed_ticks"  # a frame whose rows are of two ticks
    # Messages that decode but are refused (``MessageSchema.refusal`` and the nodes' tick and run checks):
    NON_FINITE = "non_finite"  # a field the plant acts on is NaN or infinite
    OUT_OF_RANGE = "out_of_range"  # a field the plant acts on is outside its physical range
    FUTURE_TICK = "future_tick"  # refs for a tick the plant has not measured yet
    STALE_TICK = "stale_tick"  # refs older than the plant's window (max_ref_age ticks)
    REPEATED_TICK = "repeated_tick"  # a second message for a tick already taken
    OLD_TICK = "old_tick"  # a sensor frame older than the last one stepped, same run
    FOREIGN_RUN = "foreign_run"  # a sensor frame whose run identity the plant does not confirm
    UNCONFIRMED_TICK = "unconfirmed_tick"  # a sensor frame far ahead of the last, beyond the plant's own tick
    DUPLICATE_TURBINE = "duplicate_turbine"  # a frame naming one turbine twice
    UNKNOWN_TURBINE = "unknown_turbine"  # a row for a turbine the run does not have
    NOT_OWNED = "not_owned"  # a row for a turbine its sender does not own (another shard's, or an unknown sender)


# -- binary schemas ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class WireField:
    """One field of a binary message: numpy dtype code, shape per record, unit and meaning."""

    name: str
    dtype: str  # numpy dtype code, little-endian where it matters: "<f8", "<i8", "<u2", "i1", "?"
    unit: str
    doc: str
    shape: tuple[int, ...] = ()
    columns: tuple[str, ...] = ()  # names of the elements of a vector field, in order
    limits: tuple[float, float] | None = None  # physical range [lo, hi] in ``unit``; NaN and ±inf are outside it
    when: tuple[str, str, float] | None = None  # (field, "==" or ">=", value): the rows the limits hold on


@dataclass(frozen=True)
class MessageSchema:
    """A binary message: a name, a one-byte code, a version and its fields. ``dtype`` is the packed layout."""

    name: str
    code: int
    version: int
    doc: str
    fields: tuple[WireField, ...]

    @cached_property  # built once: the live loops encode nine or more messages per 10 ms tick
    def dtype(self) -> np.dtype:
        return np.dtype([(f.name, f.dtype, f.shape) for f in self.fields])

    @cached_property
    def header(self) -> bytes:
        return np.array([(MAGIC, self.code, self.version)], dtype=HEADER).tobytes()

    @property
    def size(self) -> int:
        """Bytes on the wire, header included."""
        return HEADER.itemsize + self.dtype.itemsize

    def empty(self, n: int = 1) -> np.ndarray:
        """n zeroed records to fill field by field (``rec["sensors"] = …``)."""
        return np.zeros(n, dtype=self.dtype)

    def encode(self, record: np.ndarray | np.void) -> bytes:
        """One record (a 0-d or 1-element structured array of ``dtype``) as bytes with the header: a frame of one."""
        return self.encode_frame(np.asarray(record, dtype=self.dtype).reshape(1))

    def encode_frame(self, records: np.ndarray) -> bytes:
        """A frame: the header and every record of a structured array of ``dtype`` (1 to ``MAX_FRAME_ROWS``)."""
        rows = np.ascontiguousarray(records, dtype=self.dtype).reshape(-1)
        if not 1 <= len(rows) <= MAX_FRAME_ROWS:
            raise ValueError(f"{self.name}: a frame holds 1 to {MAX_FRAME_ROWS} rows, not {len(rows)}")
        return self.header + rows.tobytes()

    def decode_frame(self, payload: bytes) -> np.ndarray:
        """The rows of a frame (a read-only structured array); ``WireError`` when the header does not match this
        schema or the length is not a whole number of 1 to ``MAX_FRAME_ROWS`` records."""
        self._check(payload)
        body = len(payload) - HEADER.itemsize
        n, rest = divmod(body, self.dtype.itemsize)
        if rest or not 1 <= n <= MAX_FRAME_ROWS:
            raise WireError(
                DropReason.BAD_LENGTH,
                f"{self.name}: {len(payload)} bytes is not a frame of 1 to {MAX_FRAME_ROWS} records of "
                f"{self.dtype.itemsize} bytes",
            )
        return np.frombuffer(payload, dtype=self.dtype, count=n, offset=HEADER.itemsize)

    def _check(self, payload: bytes) -> None:
        code, version = check_header(payload)
        if code != self.code:
            raise WireError(DropReason.UNKNOWN_SCHEMA, f"expected {self.name} (code {self.code}), got code {code}")
        if version != self.version:
            raise WireError(DropReason.BAD_VERSION, f"{self.name}: version {version} is not {self.version}")

    def decode(self, payload: bytes) -> np.void:
        """The record in a frame of one row; ``WireError`` when the header or the length does not match."""
        self._check(payload)
        if len(payload) != self.size:
            raise WireError(DropReason.BAD_LENGTH, f"{self.name}: {len(payload)} bytes, expected {self.size}")
        return np.frombuffer(payload, dtype=self.dtype, count=1, offset=HEADER.itemsize)[0]

    @cached_property
    def limited(self) -> tuple[WireField, ...]:
        """The fields with a physical range, in declaration order."""
        return tuple(f for f in self.fields if f.limits is not None)

    @cached_property
    def range_check(self) -> RangeCheck:
        return RangeCheck(self.dtype, self.limited)

    def refusal(self, records: np.ndarray) -> DropReason | None:
        """Why the plant must refuse ``records`` (one row per turbine), or None: a limited field that is not finite
        (``NON_FINITE``) or outside its range (``OUT_OF_RANGE``) on a row where its limits hold."""
        reason = self.range_check(records)
        return None if reason is None else DropReason(reason)

    def describe(self) -> list[dict[str, Any]]:
        """The fields as a table (for docs and the API)."""
        return [
            {"field": f.name, "dtype": np.dtype(f.dtype).name, "shape": list(f.shape), "unit": f.unit, "doc": f.doc}
            | ({"columns": list(f.columns)} if f.columns else {})
            | ({"limits": list(f.limits)} if f.limits else {})
            | ({"limits_when": " ".join(map(str, f.when))} if f.when else {})
            for f in self.fields
        ]


def check_header(payload: bytes) -> tuple[int, int]:
    """(schema code, version) of a binary message; ``WireError`` when it has no valid header."""
    if len(payload) < HEADER.itemsize:
        raise WireError(DropReason.BAD_LENGTH, f"{len(payload)} bytes is shorter than the header")
    if payload[:2] != MAGIC:
        raise WireError(DropReason.BAD_MAGIC, "not a windwarden message")
    return payload[2], payload[3]


def frame_problem(rows: np.ndarray) -> DropReason | None:
    """Why the rows of one frame cannot be one tick's records of distinct turbines (``MIXED_TICKS``,
    ``DUPLICATE_TURBINE``), or None."""
    ticks = rows["tick"]
    if (ticks != ticks[0]).any():
        return DropReason.MIXED_TICKS
    turbines = rows["turbine"]
    if len(turbines) > 1 and len(np.unique(turbines)) != len(turbines):
        return DropReason.DUPLICATE_TURBINE
    return None


def stack_records(records: Sequence[np.void]) -> np.ndarray:
    """Records of one schema (one per turbine) as a structured array of n rows, in the order given."""
    return np.array(list(records), dtype=records[0].dtype) if records else np.zeros(0)


def _tick_fields() -> tuple[WireField, ...]:
    return (
        WireField("tick", "<i8", "–", "tick index k of the samples (t = k·dt)"),
        WireField("t", "<f8", "s", "simulation time of tick k"),
        WireField("turbine", "<u2", "–", "turbine number, 1-based"),
    )


def _frame_fields() -> tuple[WireField, ...]:
    """The head of every sensor frame: the tick fields and the plant's run identity."""
    return (*_tick_fields(), WireField("run", "<u8", "–", "run identity: a random number the plant draws per run"))


_SENSOR_UNITS = ", ".join(f"{c.name} [{c.unit}]" for c in SENSORS)

TURBINE_SENSORS = MessageSchema(
    "turbine.sensors",
    1,
    2,  # v2: run
    "What a benchmark turbine measures at tick k, and its controller's outputs of tick k−1 (TurbineFrame row).",
    (
        *_frame_fields(),
        WireField("sensors", "<f8", "per column", f"readings y_k: {_SENSOR_UNITS}", (N_SENSORS,), SENSOR_NAMES),
        WireField("tau_g_ref", "<f8", "N m", "converter torque reference issued at tick k−1"),
        WireField("beta_ref", "<f8", "deg", "collective pitch reference issued at tick k−1"),
        WireField("power_ref", "<f8", "W", "power reference the controller used at tick k−1"),
        WireField("zone", "i1", "–", "controller zone at tick k−1 (0 region 2, 1 region 3)"),
    ),
)

TURBINE_REFS = MessageSchema(
    "turbine.refs",
    2,
    1,
    "The supervisor's references for one turbine, computed from sensors of tick ``tick`` (TurbineRefs row), "
    "plus the non-fault-tolerant estimate and the selected observer for display and scoring.",
    (
        WireField("tick", "<i8", "–", "tick of the sensor frame these refs were computed from"),
        WireField("turbine", "<u2", "–", "turbine number, 1-based"),
        WireField("valid", "?", "–", "the estimates may be used by the controller"),
        WireField("omega_g", "<f8", "rad/s", "fault-tolerant generator speed estimate"),
        WireField("omega_r", "<f8", "rad/s", "fault-tolerant rotor speed estimate"),
        WireField("wind", "<f8", "m/s", "fault-tolerant rotor-effective wind estimate (FTE)"),
        WireField("power_ref_set", "?", "–", "power_ref carries a reference (farm dispatch); false keeps P_r"),
        WireField("power_ref", "<f8", "W", "per-turbine power reference, when power_ref_set"),
        WireField("nfte_set", "?", "–", "wind_nfte carries an estimate"),
        WireField("wind_nfte", "<f8", "m/s", "non-fault-tolerant wind estimate (observer 1 throughout), display"),
        WireField("selected", "<i2", "–", "index of the observer in use (−1 none)"),
    ),
)
TURBINE_REFS = with_limits(TURBINE_REFS, TURBINE_REFS_LIMITS)

TURBINE_TRUTH = MessageSchema(
    "turbine.truth",
    3,
    1,
    "Ground truth of one turbine, for display and scoring only; the supervisor never subscribes to it.",
    (
        *_tick_fields(),
        WireField("omega_r", "<f8", "rad/s", "rotor speed"),
        WireField("omega_g", "<f8", "rad/s", "generator speed"),
        WireField("pitch", "<f8", "deg", "blade pitch angles", (3,), ("beta_1", "beta_2", "beta_3")),
        WireField("tau_g", "<f8", "N m", "generator torque"),
        WireField("power", "<f8", "W", "electrical power"),
        WireField("tau_aero", "<f8", "N m", "aerodynamic torque"),
        WireField("wind_rotor", "<f8", "m/s", "true rotor-effective wind"),
        WireField("wind_hub", "<f8", "m/s", "true hub-height wind"),
        WireField("zone", "i1", "–", "controller zone"),
    ),
)

HYDRO_SENSORS = MessageSchema(
    "hydro.sensors",
    4,
    2,  # v2: run
    "What the hydrostatic turbine measures at tick k and the commands it received over tick k−1 (HydroFrame row).",
    (
        *_frame_fields(),
        WireField("y", "<f8", ", ".join(Y_UNITS), "measured outputs y_k (with noise)", (len(Y_NAMES),), Y_NAMES),
        WireField("u", "<f8", "–, –, N m", "commands sent over tick k−1 (after correction)", (len(U_NAMES),), U_NAMES),
    ),
)

HYDRO_REFS = MessageSchema(
    "hydro.refs",
    5,
    1,
    "The supervisor's virtual-actuator correction (eq. 36) and its reconstruction (HydroRefs row).",
    (
        *_tick_fields(),
        WireField("correction", "<f8", "–", "f̂_a,filt to subtract from [u_p, u_M]", (2,), FAULT_TARGETS),
        WireField("apply", "?", "–", "the correction is valid and compensation is on"),
        WireField("f_hat", "<f8", "–", "unfiltered reconstruction, eq. (35)", (2,), FAULT_TARGETS),
        WireField("x_hat", "<f8", "SI per state", "observer states", (len(X_NAMES),), X_NAMES),
        WireField("flagged", "?", "–", "the detector flags [u_p, u_M] as faulty", (2,), FAULT_TARGETS),
    ),
)
HYDRO_REFS = with_limits(HYDRO_REFS, HYDRO_REFS_LIMITS)

HYDRO_TRUTH = MessageSchema(
    "hydro.truth",
    6,
    1,
    "Ground truth of the hydrostatic turbine, for display and scoring only.",
    (
        *_tick_fields(),
        WireField("x", "<f8", "SI per state", "true states", (len(X_NAMES),), X_NAMES),
        WireField("f", "<f8", "–", "true actuator offsets f_a acting over [t_k, t_k+1)", (2,), FAULT_TARGETS),
        WireField("v", "<f8", "m/s", "rotor-effective wind"),
        WireField("P_g", "<f8", "W", "generator power"),
        WireField("u_nominal", "<f8", "–, –, N m", "the baseline controller's commands", (3,), U_NAMES),
        WireField("u_applied", "<f8", "–, –, N m", "what the actuators received (faults included)", (3,), U_NAMES),
    ),
)

METMAST = MessageSchema(
    "farm.metmast",
    7,
    1,
    "The farm's met mast (farm kind).",
    (
        WireField("tick", "<i8", "–", "tick index"),
        WireField("t", "<f8", "s", "simulation time"),
        WireField("wind_speed", "<f8", "m/s", "measured wind speed"),
        WireField("wind_direction", "<f8", "deg", "measured wind direction, from north, clockwise"),
    ),
)


FARM_SENSORS = MessageSchema(
    "farm.sensors",
    8,
    3,  # v2: run; v3: mast_direction
    "One farm turbine's frame at tick k (FarmFrame row): its own sensors and controller outputs (as turbine.sensors), "
    "and on 10 Hz farm samples its SCADA means, the met mast and the farm demand (the same on every turbine's row).",
    (
        *_frame_fields(),
        WireField("sensors", "<f8", "per column", f"readings y_k: {_SENSOR_UNITS}", (N_SENSORS,), SENSOR_NAMES),
        WireField("tau_g_ref", "<f8", "N m", "converter torque reference issued at tick k−1"),
        WireField("beta_ref", "<f8", "deg", "collective pitch reference issued at tick k−1"),
        WireField("power_ref", "<f8", "W", "power reference the controller used at tick k−1"),
        WireField("zone", "i1", "–", "controller zone at tick k−1 (0 region 2, 1 region 3 / derated)"),
        WireField("sample", "?", "–", "tick k closes a 10 Hz farm sample: the fields below are new"),
        WireField("scada", "<f8", "per column", "means of the last ten readings", (N_SENSORS,), SENSOR_NAMES),
        WireField("power_ref_used", "<f8", "W", "mean power reference of the last ten ticks"),
        WireField("mast", "<f8", "m/s", "met-mast wind reading (10 Hz, held)"),
        WireField("demand", "<f8", "W", "farm power demand P_ref,farm"),
        WireField("mast_direction", "<f8", "deg", "met-mast vane reading, from north, clockwise (10 Hz, held)"),
    ),
)

FARM_REFS = MessageSchema(
    "farm.refs",
    9,
    3,  # v2: held_torque; v3: modes 4 and 5, pitch_trim, ripple_power, ripple_rate
    "The farm supervisor's power reference for one turbine (FarmRefs row), with its detector's view of the turbine.",
    (
        WireField("tick", "<i8", "–", "tick of the sensor frame these refs answer"),
        WireField("turbine", "<u2", "–", "turbine number, 1-based"),
        WireField("computed_tick", "<i8", "–", "tick of the 10 Hz farm sample the reference was computed from"),
        WireField("power_ref", "<f8", "W", "per-turbine power reference P_ref,t"),
        WireField("flags", "?", "–", "fault flagged, per fault type", (3,), FARM_FAULT_TYPES),
        WireField(
            "statistic", "<f8", "–", "test statistic per fault type (CUSUM g or 3P amplitude)", (3,), FARM_FAULT_TYPES
        ),
        WireField("threshold", "<f8", "–", "its alarm threshold (NaN: no test)", (3,), FARM_FAULT_TYPES),
        WireField(
            "mode",
            "i1",
            "–",
            "accommodation: 0 none, 1 debris (23)–(24), 2 derated (26), 3 derated at held torque, 4 pitch trim, "
            "5 normal laws with the 3P torque cancelled",
        ),
        WireField(
            "held_torque", "<f8", "N m", "mode 3: the most generator-side torque sum S = τ_g + B_g ω_g the hold keeps"
        ),
        WireField(
            "pitch_trim",
            "<f8",
            "deg",
            "added to each blade's pitch command (mode 4)",
            (3,),
            ("blade_1", "blade_2", "blade_3"),
        ),
        WireField(
            "ripple_power",
            "<f8",
            "W",
            "phasor C: the turbine adds Re{C e^{jω(t − t_c)}} to its power, t_c = (computed_tick + 1)·Δt",
            (2,),
            ("re", "im"),
        ),
        WireField("ripple_rate", "<f8", "rad/s", "ω of ripple_power (0: none)"),
    ),
)
FARM_REFS = with_limits(FARM_REFS, FARM_REFS_LIMITS)

FARM_SUMMARY = MessageSchema(
    "farm.summary",
    11,
    1,
    "A supervisor shard's summary of one of its turbines at a 10 Hz farm sample, for the farm coordinator: the "
    "sample as the plant sent it (farm.sensors) and the shard's detector's verdict on the turbine "
    "(``windwarden.live.shard``).",
    (
        *_frame_fields(),
        WireField("sample_index", "<i8", "–", "farm sample index j (sample time j·0.1 s)"),
        WireField("sample_t", "<f8", "s", "farm sample time j·0.1 s"),
        WireField("scada", "<f8", "per column", "means of the last ten readings", (N_SENSORS,), SENSOR_NAMES),
        WireField("zone", "i1", "–", "controller zone at tick k−1 (0 region 2, 1 region 3 / derated)"),
        WireField("power_ref_used", "<f8", "W", "mean power reference of the last ten ticks"),
        WireField("mast", "<f8", "m/s", "met-mast wind reading (10 Hz, held)"),
        WireField("demand", "<f8", "W", "farm power demand P_ref,farm"),
        WireField("mast_direction", "<f8", "deg", "met-mast vane reading, from north, clockwise (10 Hz, held)"),
        WireField("flags", "?", "–", "the shard's detector flags, per fault type", (3,), FARM_FAULT_TYPES),
        WireField("statistic", "<f8", "–", "test statistic per fault type", (3,), FARM_FAULT_TYPES),
        WireField("threshold", "<f8", "–", "its alarm threshold (NaN: no test)", (3,), FARM_FAULT_TYPES),
    ),
)
FINITE = (-sys.float_info.max, sys.float_info.max)
FARM_SUMMARY = with_limits(
    FARM_SUMMARY,
    {
        "sample_index": (0, 2**62, None),
        "sample_t": (0.0, FINITE[1], None),
        "scada": (*FINITE, None),  # the plant's readings: any finite value (a faulty sensor reads what it reads)
        "zone": (0, 1, None),
        "power_ref_used": (0.0, POWER_MAX, None),  # W
        "mast": (0.0, MAST_WIND_MAX, None),  # m/s
        "demand": (0.0, FARM_DEMAND_MAX, None),  # W
        "mast_direction": (0.0, 360.0, None),  # deg
        "statistic": (0.0, FINITE[1], None),  # a CUSUM g or a 3P amplitude: never negative
    },
)
"""What the coordinator takes from a shard: every field it computes with is finite and in its range (the
thresholds are display only and may be NaN)."""

FARM_TRUTH = MessageSchema(
    "farm.truth",
    10,
    2,  # v2: wind_direction
    "Ground truth of one farm turbine and of its farm, for display and scoring only.",
    (
        *_tick_fields(),
        WireField("omega_r", "<f8", "rad/s", "rotor speed"),
        WireField("omega_g", "<f8", "rad/s", "generator speed"),
        WireField("pitch", "<f8", "deg", "blade pitch angles", (3,), ("beta_1", "beta_2", "beta_3")),
        WireField("power", "<f8", "W", "electrical power output"),
        WireField("power_ref", "<f8", "W", "the reference the turbine controller follows (ramp-limited)"),
        WireField("shaft_torque", "<f8", "N m", "low-speed shaft torque"),
        WireField("wind_rotor", "<f8", "m/s", "true rotor-effective wind"),
        WireField("row_wind", "<f8", "m/s", "mean wind of the turbine's row (delayed mast wind, waked)"),
        WireField("zone", "i1", "–", "controller zone"),
        WireField("farm_power", "<f8", "W", "the farm's total output"),
        WireField(
            "wind_direction",
            "<f8",
            "deg",
            "true direction (from north, clockwise, 0 … <360) of the air at the turbine: the mast's, carried "
            "across the farm with the wind (docs/farm.md §1.9)",
        ),
    ),
)
FARM_TRUTH = with_limits(FARM_TRUTH, {"wind_direction": (0.0, 360.0, None)})
"""Truth is never acted on; its ranges say what a row may hold (``MessageSchema.refusal`` checks a recorded one)."""

SCHEMAS: dict[str, MessageSchema] = {
    s.name: s
    for s in (
        TURBINE_SENSORS,
        TURBINE_REFS,
        TURBINE_TRUTH,
        HYDRO_SENSORS,
        HYDRO_REFS,
        HYDRO_TRUTH,
        METMAST,
        FARM_SENSORS,
        FARM_REFS,
        FARM_TRUTH,
        FARM_SUMMARY,
    )
}
if len({s.code for s in SCHEMAS.values()}) != len(SCHEMAS):  # pragma: no cover - a declaration error
    raise RuntimeError("two wire schemas share a code")


# -- JSON (control plane) ------------------------------------------------------------------------------------------
JSON_SCHEMAS: dict[str, int] = {
    "events": 1,  # body: wwcore.events.Event.to_json()
    "plant.status": 1,  # body: run status (simulation time, speed, overruns, latency, liveliness)
    "plant.run": 2,  # body: RunInfo, what the supervisor may know (its SiteInfo: no faults, no wind, no truth)
    "plant.faults": 1,  # query body: {"op": "inject"|"clear"|"list", ...}; reply body: {"ok": …}
    "supervisor.status": 1,  # body: {"t", "tick", "turbines": [per-turbine status]}
    "shard.status": 1,  # body: a supervisor shard's run, turbines and readiness (windwarden.live.shard)
}
"""Name → current version of each JSON message."""


def encode_json(schema: str, body: Mapping[str, Any]) -> bytes:
    return json.dumps({"schema": schema, "v": JSON_SCHEMAS[schema], "body": body}, allow_nan=False).encode()


def decode_json(schema: str, payload: bytes) -> dict[str, Any]:
    """The body of a JSON message of ``schema``; ``WireError`` for anything else."""
    if len(payload) > MAX_JSON_BYTES:
        raise WireError(DropReason.BAD_LENGTH, f"{len(payload)} bytes is more than {MAX_JSON_BYTES}")
    try:
        message = json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise WireError(DropReason.BAD_BODY, f"not JSON: {error}") from None
    if not isinstance(message, dict) or message.get("schema") != schema:
        raise WireError(DropReason.UNKNOWN_SCHEMA, f"expected a {schema!r} message")
    if message.get("v") != JSON_SCHEMAS[schema]:
        raise WireError(DropReason.BAD_VERSION, f"{schema}: version {message.get('v')!r} is not {JSON_SCHEMAS[schema]}")
    body = message.get("body")
    if not isinstance(body, dict):
        raise WireError(DropReason.BAD_BODY, f"{schema}: body is not an object")
    return body
