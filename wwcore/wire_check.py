"""What a receiver does with messages it cannot trust: check them against their fields' physical ranges, count drops.

``RangeCheck`` compiles the ranges of a schema's fields (``wwcore.wire.WireField.limits``) into a fast check;
``wwcore.wire.MessageSchema.refusal`` uses it. It knows nothing of the schemas but their packed dtype and the fields
that carry limits (objects with ``name``, ``limits`` and ``when``). ``DropCounter`` counts what receivers drop
(``wwcore.wire`` exports it with the codec).
"""

from __future__ import annotations

import math
import struct
import threading
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

NON_FINITE = "non_finite"  # wwcore.wire.DropReason.NON_FINITE
OUT_OF_RANGE = "out_of_range"  # wwcore.wire.DropReason.OUT_OF_RANGE

_STRUCT_CODES = {"<f8": "d", "|i1": "b", "|b1": "?", "<i8": "q"}  # numpy dtype → struct code, little-endian


def _int_bound(bound: float, to_int: Callable[[float], int]) -> int:
    """An integer x satisfies ``lo <= x`` iff ``ceil(lo) <= x`` and ``x <= hi`` iff ``x <= floor(hi)``; clipped to
    int64 (infinite bounds: the type's own)."""
    if math.isinf(bound):
        return -(2**63) if bound < 0 else 2**63 - 1
    return max(-(2**63), min(2**63 - 1, to_int(bound)))


class RangeCheck:
    """A schema's limits compiled once, checked two ways that give the same verdict (``tests/live/test_guard.py``):

    * ``by_rows``: one ``struct`` unpack per row of exactly the values the limits need (the limited values and the
      conditions' fields, at their byte offsets), then one comparison per value. For a message of a few rows (one
      turbine, the nine of the 3 × 3) this is 2–10 times cheaper than the dozen numpy calls a vectorised check
      takes (``tools/bench_guard.py``);
    * ``by_columns``: the same values gathered from every row at once, a few dozen numpy calls whose cost hardly
      grows with the rows: used from ``COLUMNS_FROM_VALUES`` values per message on (measured crossover: ~45 rows
      of ``farm.refs``, 9 values a row; ~22 rows of ``farm.summary``, 23 a row). For Horns Rev 1's 80 rows it is
      1.3 (refs) and 2.6 (summaries) times cheaper (``tests/live/test_guard.py`` checks both against a plain
      implementation).

    NaN fails every comparison, so it is caught with the range; a value outside its range on a row where its limits
    hold is ``NON_FINITE`` if any such value is NaN or ±inf, else ``OUT_OF_RANGE``."""

    COLUMNS_FROM_VALUES = 400  # rows × values checked per row from which ``by_columns`` is the cheaper

    def __init__(self, dtype: np.dtype, limited: Sequence[Any]):
        reads: dict[int, np.dtype] = {}  # byte offset → dtype of each value read

        def read(offset: int, value_dtype: np.dtype) -> int:
            reads.setdefault(offset, value_dtype)
            return offset

        checks = []
        for f in limited:
            field_dtype, offset = dtype.fields[f.name][:2]
            base = field_dtype.base
            condition = None
            if f.when is not None:
                name, op, value = f.when
                if op not in ("==", ">="):  # pragma: no cover - a declaration error
                    raise ValueError(f"unsupported limit condition {f.when}")
                when_dtype, when_offset = dtype.fields[name][:2]
                condition = (read(when_offset, when_dtype), op == ">=", value)
            for i in range(int(np.prod(field_dtype.shape, dtype=int))):
                checks.append((read(offset + base.itemsize * i, base), *f.limits, condition))  # type: ignore[misc]
        fmt, end, slot = "<", 0, {}
        for offset in sorted(reads):
            fmt += (f"{offset - end}x" if offset > end else "") + _STRUCT_CODES[reads[offset].str]
            slot[offset] = len(slot)
            end = offset + reads[offset].itemsize
        self.row = struct.Struct(fmt + (f"{dtype.itemsize - end}x" if dtype.itemsize > end else ""))
        self.checks = [(slot[at], lo, hi, None if c is None else (slot[c[0]], c[1], c[2])) for at, lo, hi, c in checks]
        self._compile_columns(dtype, reads, checks)

    def _compile_columns(self, dtype: np.dtype, reads: dict[int, np.dtype], checks: list[tuple]) -> None:
        """``by_columns``'s plan. The values are gathered from the rows' bytes into two arrays of rows × values:
        the 8-byte floats and the 1-byte integers and bools as float64 (exact), the 8-byte integers as int64 (kept
        exact: a tick near 2**62 is not a float). Each condition becomes a column of booleans computed once,
        exactly in its field's type; the float values are checked as one array, the few integer ones one by one
        with integer bounds."""
        self.itemsize = dtype.itemsize
        floats = [o for o in sorted(reads) if _STRUCT_CODES[reads[o].str] != "q"]
        ints = [o for o in sorted(reads) if _STRUCT_CODES[reads[o].str] == "q"]
        self.float_at = {o: i for i, o in enumerate(floats)}
        self.int_at = {o: i for i, o in enumerate(ints)}
        self.gathers = []  # (into the ints, their slots, columns start:stop of the picked bytes, dtype)
        picked: list[int] = []  # the bytes read of a row, by type
        for code, view, into in (("d", "<f8", False), ("b", "i1", False), ("?", "i1", False), ("q", "<i8", True)):
            at = [o for o in sorted(reads) if _STRUCT_CODES[reads[o].str] == code]
            if at:
                size = np.dtype(view).itemsize
                slots = np.array([(self.int_at if into else self.float_at)[o] for o in at], dtype=np.intp)
                self.gathers.append((into, slots, len(picked), len(picked) + size * len(at), view))
                picked += [o + i for o in at for i in range(size)]
        self.picked = np.array(picked, dtype=np.intp)
        self._last: tuple[bytes, str | None] | None = None  # the bytes picked last and their verdict
        conditions = sorted({c for *_, c in checks if c is not None}, key=repr)
        self.conditions = [(c[0] in self.int_at, *c) for c in conditions]  # column of holds j ← conditions[j]
        always = len(conditions)  # the last column of holds: True (no condition)
        float_checks = [c for c in checks if c[0] in self.float_at]
        self.value_at = np.array([self.float_at[c[0]] for c in float_checks], dtype=np.intp)
        self.lo = np.array([c[1] for c in float_checks], dtype=float)
        self.hi = np.array([c[2] for c in float_checks], dtype=float)
        self.holds_at = np.array(
            [always if c[3] is None else conditions.index(c[3]) for c in float_checks], dtype=np.intp
        )
        self.int_checks = [  # (column, lowest, highest integer in range, holds column)
            (
                self.int_at[at],
                _int_bound(lo, math.ceil),
                _int_bound(hi, math.floor),
                always if c is None else conditions.index(c),
            )
            for at, lo, hi, c in checks
            if at in self.int_at
        ]

    def __call__(self, records: np.ndarray) -> str | None:
        """The verdict on ``records``: ``by_rows`` for a small message; for a large one ``by_columns``, or, when the
        values it reads are byte for byte those of the last large message checked, that message's verdict (the
        supervisor answers nine ticks in ten with the references of the last farm sample, re-stamped)."""
        if len(records) * len(self.checks) < self.COLUMNS_FROM_VALUES:
            return self.by_rows(records)
        picked = self._pick(records)
        key = picked.tobytes()
        last = self._last
        if last is not None and last[0] == key:
            return last[1]
        verdict = self._by_columns(picked)
        self._last = (key, verdict)
        return verdict

    def _pick(self, records: np.ndarray) -> np.ndarray:
        """The bytes the limits read, rows × bytes, by type (``gathers``)."""
        raw = np.ascontiguousarray(records).view(np.uint8).reshape(len(records), self.itemsize)
        return raw.take(self.picked, axis=1)

    def by_columns(self, records: np.ndarray) -> str | None:
        return self._by_columns(self._pick(records))

    def _by_columns(self, picked: np.ndarray) -> str | None:
        n = len(picked)
        floats, ints = np.empty((n, len(self.float_at))), np.empty((n, len(self.int_at)), dtype=np.int64)
        for into_ints, slots, start, stop, view in self.gathers:
            (ints if into_ints else floats)[:, slots] = picked[:, start:stop].view(view)
        holds = np.ones((n, len(self.conditions) + 1), dtype=bool)
        for j, (on_int, at, at_least, value) in enumerate(self.conditions):
            c = ints[:, self.int_at[at]] if on_int else floats[:, self.float_at[at]]
            if on_int and at_least:
                holds[:, j] = c >= math.ceil(value)
            elif on_int:
                holds[:, j] = c == int(value) if float(value).is_integer() else False
            else:
                holds[:, j] = c >= value if at_least else c == value
        x = floats[:, self.value_at]  # rows × float checks
        checked = ~((self.lo <= x) & (x <= self.hi)) & holds[:, self.holds_at]
        if checked.any() and not np.isfinite(x[checked]).all():
            return NON_FINITE
        outside = bool(checked.any())
        for column, lo, hi, h in self.int_checks:
            c = ints[:, column]
            outside = outside or bool((((c < lo) | (c > hi)) & holds[:, h]).any())
        return OUT_OF_RANGE if outside else None

    def by_rows(self, records: np.ndarray) -> str | None:
        outside = False
        for row in self.row.iter_unpack(records.tobytes()):
            for at, lo, hi, condition in self.checks:
                x = row[at]
                if lo <= x <= hi:
                    continue
                if condition is not None:
                    c, at_least, value = condition
                    if not (row[c] >= value if at_least else row[c] == value):
                        continue  # the limits do not hold on this row
                if not math.isfinite(x):
                    return NON_FINITE
                outside = True
        return OUT_OF_RANGE if outside else None


def with_limits(schema: Any, limits: dict[str, tuple[float, float, tuple[str, str, float] | None]]) -> Any:
    """``schema`` with physical ranges on some of its fields: name → (lo, hi, when), in the field's unit."""
    fields = tuple(
        replace(f, limits=limits[f.name][:2], when=limits[f.name][2]) if f.name in limits else f for f in schema.fields
    )
    return replace(schema, fields=fields)


class DropCounter:
    """Messages dropped by a receiver, by (stream, reason). Safe to bump from any thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.counts: Counter[tuple[str, str]] = Counter()
        self.version = 0  # bumped by every add: a reader polls it without taking the lock

    def add(self, stream: str, reason: str) -> None:
        with self._lock:
            self.counts[(stream, str(reason))] += 1
            self.version += 1

    def of(self, stream: str) -> dict[str, int]:
        """Counts of one stream, by reason."""
        with self._lock:
            return {reason: n for (s, reason), n in self.counts.items() if s == stream}

    def total(self) -> int:
        with self._lock:
            return sum(self.counts.values())

    def as_dict(self) -> dict[str, int]:
        with self._lock:
            return {f"{stream}:{reason}": n for (stream, reason), n in sorted(self.counts.items())}
