"""The events a supervisor logs about its rows, the same for every plant kind: DETECTION / RECOVERY when a flag
changes (``flag_events``) and any other event of one row (``row_event``: an observer switch, a dispatch mode)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from wwcore.events import Event, EventType


def row_event(
    t: float,
    kind: EventType,
    row: int,
    turbine_of_row: Sequence[int],
    run_of_row: Sequence[int],
    target: str | None = None,
    detail: dict[str, Any] | None = None,
) -> Event:
    """One event of batch row ``row`` (its turbine number and run from the two per-row tables)."""
    return Event(
        t=t, type=kind, turbine=int(turbine_of_row[row]), target=target, run=int(run_of_row[row]), detail=detail or {}
    )


def flag_events(
    t: float,
    old: np.ndarray,
    new: np.ndarray,
    targets: Sequence[str],
    turbine_of_row: Sequence[int],
    run_of_row: Sequence[int],
    detail: Callable[[int, int], dict[str, Any]] | None = None,
) -> list[Event]:
    """DETECTION (raised) or RECOVERY (cleared) for every (row, column) whose flag differs between ``old`` and
    ``new`` (rows × targets), in row-major order; ``detail(row, column)`` adds what the kind reports with it."""
    changed = new != old
    if not changed.any():
        return []
    return [
        row_event(
            t,
            EventType.DETECTION if new[row, col] else EventType.RECOVERY,
            row,
            turbine_of_row,
            run_of_row,
            targets[col],
            detail(row, col) if detail is not None else None,
        )
        for row, col in zip(*np.nonzero(changed), strict=True)
    ]
