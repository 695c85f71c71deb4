"""Non-finite readings in the sensor frames the supervisor steps: held at the channel's last finite value.

A sensor that dies, a broken cable or a simulator bug can put NaN or ±inf into one reading of a frame whose other
readings are good. The observers and detectors are linear filters and sums: one NaN stepped into them poisons their
state for the rest of the run (a NaN rotor-speed reading for one tick turns every later reference into NaN, which
the plant refuses, so the turbine runs on its fallback controller from then on). Refusing the whole frame instead
would stop the supervisor for as long as the one sensor stays dead.

``ReadingHold`` sits between the sequencer and the supervisor (``supervisor_node``, ``batch.run_batch``): every
non-finite float of a frame (each column of ``sensors``, ``scada``, ``y``, ``u``, the controller outputs and the
mast; every field but ``t``) is replaced by the last finite value of the same turbine row and column, and counted
by channel (``held``). A dead sensor so reaches the supervisor as a sensor stuck at its last reading: a fault the
detectors are built to find (a fixed-value fault, Odgaard's benchmark's kind), and the observers keep running on the
healthy sensors once it is flagged. A frame is refused (``non_finite``, counted as a dropped frame, changing nothing)
when its time ``t`` is not finite, or a reading is not finite before that channel has had any finite value in this
run: there is nothing to hold yet.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from wwcore.wire import MessageSchema


class ReadingHold:
    """Holds non-finite readings at the last finite one (module docstring); one per run (``restart`` when the
    observers restart within it)."""

    def __init__(self, schema: MessageSchema):
        floats = [f for f in schema.fields if np.dtype(f.dtype).kind == "f"]
        self.fields = tuple(f.name for f in floats if f.name != "t")  # the float fields a frame's readings are in
        self.columns = {f.name: f.columns for f in floats}
        dtype = schema.dtype
        self._float_bytes = np.concatenate(  # where a record's floats are, ``t`` included: one gather checks them all
            [np.arange(dtype.fields[f.name][1], dtype.fields[f.name][1] + dtype[f.name].itemsize) for f in floats]
        )
        self._itemsize = dtype.itemsize
        self.last: np.ndarray | None = None  # the last frame passed on (every float finite); None before the first
        self.held: Counter[str] = Counter()  # readings held, by channel ("sensors.omega_r_m1", "mast", …)

    def restart(self) -> None:
        """The supervisor starts afresh within the run: no reading from before is held; the counts stay."""
        self.last = None

    def take(self, records: np.ndarray) -> np.ndarray | None:
        """``records`` with every non-finite reading held (a copy if one was), or None to refuse the frame."""
        raw = np.ascontiguousarray(records).view(np.uint8).reshape(len(records), self._itemsize)
        if np.isfinite(raw.take(self._float_bytes, axis=1).view("<f8")).all():
            self.last = records
            return records
        if not np.isfinite(records["t"]).all():
            return None
        bad = {name: ~np.isfinite(records[name]) for name in self.fields}
        last = self.last
        if last is None or len(last) != len(records):
            return None
        out = records.copy()
        for name, b in bad.items():
            if not b.any():
                continue
            out[name][b] = last[name][b]
            self._count(name, b)
        self.last = out
        return out

    def _count(self, name: str, bad: np.ndarray) -> None:
        columns = self.columns[name]
        if bad.ndim == 1 or not columns:
            self.held[name] += int(bad.sum())
            return
        for column, n in zip(columns, bad.sum(axis=0), strict=True):
            if n:
                self.held[f"{name}.{column}"] += int(n)
