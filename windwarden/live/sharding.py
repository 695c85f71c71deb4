"""What a supervisor shard and the farm coordinator put on the wire, and what they make of it (no transport here).

A shard (``windwarden.live.shard``) steps the per-turbine part of the farm supervisor on its turbines
(``service.farm.shard.FarmShard``) and, on each 10 Hz farm sample, sends one ``farm.summary`` frame, a row per
turbine: the sample as the plant sent it and its detector's verdict (``summary_records``). The coordinator
(``windwarden.live.coordinator``) assembles the farm's sample and diagnosis from every turbine's summary
(``farm_sample``), runs the farm-wide part (``FarmSupervisor.decide``: the dispatch, eqs. (18)–(26), the
accommodation, the events) and sends every turbine's references back as one ``farm.refs`` frame on the dispatch key;
the shard answers each sensor tick with the newest of them, re-stamped (``held_records``), as one supervisor does.
"""

from __future__ import annotations

import numpy as np

from service.farm.interfaces import FarmDiagnosis, FarmSample
from windwarden.kinds.base import records_from_batch
from wwcore.wire import FARM_REFS, FARM_SUMMARY, DropReason, MessageSchema, WireError


def summary_records(sensors: np.ndarray, sample: FarmSample, diagnosis: FarmDiagnosis) -> np.ndarray:
    """``farm.summary`` rows of a shard's turbines: ``sensors`` (their ``farm.sensors`` rows of a farm sample, as
    received: SCADA means not untrimmed), ``sample`` and ``diagnosis`` (the shard's, same rows)."""
    values = {
        "tick": sensors["tick"],
        "t": sensors["t"],
        "run": sensors["run"],
        "sample_index": sample.j,
        "sample_t": sample.t,
        "scada": sensors["scada"],
        "zone": sensors["zone"],
        "power_ref_used": sensors["power_ref_used"],
        "mast": sensors["mast"],
        "demand": sensors["demand"],
        "mast_direction": sensors["mast_direction"],
        "flags": diagnosis.faulty,
        "statistic": diagnosis.statistics,
        "threshold": diagnosis.thresholds,
    }
    return records_from_batch(FARM_SUMMARY, values, [int(t) for t in sensors["turbine"]])


def farm_sample(summaries: np.ndarray) -> tuple[FarmSample, FarmDiagnosis]:
    """The farm's sample (as the plant sent it) and its detectors' diagnosis from one farm's summaries of one tick,
    rows in the farm's turbine order; the met mast and the demand from the first row, as
    ``FarmKind.frame_from_records`` takes them."""
    sample = FarmSample(
        j=int(summaries["sample_index"][0]),
        t=float(summaries["sample_t"][0]),
        scada=np.array(summaries["scada"]),
        zone=np.array(summaries["zone"]),
        power_ref_used=np.array(summaries["power_ref_used"]),
        mast=np.array(summaries["mast"][:1]),
        demand=np.array(summaries["demand"][:1]),
        mast_direction=np.array(summaries["mast_direction"][:1]),
    )
    diagnosis = FarmDiagnosis(
        np.array(summaries["flags"]), np.array(summaries["statistic"]), np.array(summaries["threshold"])
    )
    return sample, diagnosis


def mismatch(summaries: np.ndarray) -> str | None:
    """Why the rows of one tick's summaries cannot be one farm sample (rows of different samples or runs), or None."""
    for name in ("run", "sample_index", "sample_t", "mast", "demand", "mast_direction"):
        column = summaries[name]
        if (column != column[0]).any():
            return f"the summaries of tick {int(summaries['tick'][0])} differ in {name}"
    return None


def held_records(last: np.ndarray | None, tick: int, turbines: list[int]) -> np.ndarray:
    """The ``farm.refs`` rows answering sensor tick ``tick``: the coordinator's newest (``last``) re-stamped, as
    ``FarmSupervisor.step`` re-stamps its references between farm samples; before the first farm sample, rows
    with no reference (``computed_tick`` −1: the turbines keep their own)."""
    if last is None:
        values = {"tick": tick, "computed_tick": -1, "power_ref": np.nan, "held_torque": np.nan}
        return records_from_batch(FARM_REFS, values, turbines)
    out = last.copy()
    out["tick"] = tick
    return out


def pitch_trim_of(dispatch: np.ndarray) -> np.ndarray | None:
    """The pitch trim (rows, 3) deg the coordinator commands in ``dispatch`` rows; None when it commands none (as
    ``FarmSupervisor`` keeps ``refs.pitch_trim`` None then)."""
    trim = np.array(dispatch["pitch_trim"])
    return trim if trim.any() else None


def checked(schema: MessageSchema, payload: bytes) -> DropReason | None:
    """Why a receiver must refuse the frame ``payload`` before it is assembled (undecodable, or a field the receiver
    computes with not finite or out of its range on any row: ``MessageSchema.refusal``), or None."""
    try:
        rows = schema.decode_frame(payload)
    except WireError as error:
        return DropReason(error.reason)
    return schema.refusal(rows)
