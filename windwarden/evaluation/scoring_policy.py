"""The scoring policy: every constant the detection figures depend on, as data, one entry per plant kind.

``windwarden eval`` and the live run folder read these and nothing else (``scoring.score_detection``), and
``docs/scorecards.md`` shows what ``policy_table()`` renders from them (a test holds the two together). A value differs
between kinds only where the plant's physics or the published method makes it differ; each says why.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

TIME_DECIMALS = 6
"""Event times and fault windows are rounded to the microsecond before scoring (as ``Event.scoring_key``), so an
event on a fault's first tick is never pushed out of its window by the tick time's last binary digit."""


@dataclass(frozen=True)
class ScoringPolicy:
    """How one plant kind's event logs are scored (``docs/scorecards.md``).

    * ``warmup_s``: scoring starts here. Flags raised before and still up at this moment count as raised at this
      moment; nothing earlier is scored, and the time before it is in no time base.
    * ``grace_s``: a fault window's scored span is [start, end + grace). Flags of the fault's own targets may
      still be up in the grace (its end must be recognised inside it); any other flag raised inside the span is a
      wrong isolation of that window, never a false alarm and never a detection.
    * ``time_base``: what one second of the false-alarm rates' denominator is.
    """

    kind: str
    warmup_s: float
    grace_s: float
    time_base: str
    warmup_reason: str
    grace_reason: str

    def as_dict(self) -> dict[str, Any]:
        """The policy as it goes into every scorecard (``scorecard["scoring"]``), reasons left out."""
        out = asdict(self)
        del out["warmup_reason"], out["grace_reason"]
        return out


TURBINE = ScoringPolicy(
    kind="turbine",
    warmup_s=10.0,
    grace_s=2.0,
    time_base="turbine-seconds",
    warmup_reason="the observers start from a nominal state, not the plant's, and the shipped detectors and "
    "estimator take no decision in their first 5 s (their `warmup_s`); the other 5 s let the controller's start "
    "transient settle and are nine time constants of the 0.3 Hz wind-estimate filter (0.53 s) that starts with "
    "the estimator's decisions. The wind RMSE leaves out the same 10 s",
    grace_reason="after a sensor or actuator fault ends, the observers' states carry the faulty readings for a few "
    "ticks and the pitch loop (actuator ω_n 11.11 rad/s, ζ 0.6) settles in well under a second; 2 s leaves room "
    "for a clearing test with persistence, 20 times the observer bank's measured ≤ 0.1 s",
)

FARM_TIME_BASE = "turbine-seconds ({n} per farm-second); Table 5 per farm-second, the paper's basis"
FARM = ScoringPolicy(
    kind="farm",
    warmup_s=60.0,
    grace_s=10.0,
    time_base=FARM_TIME_BASE.format(n=9),
    warmup_reason="the paper's wind-direction estimate averages 500 farm samples (50 s at 10 Hz) before the "
    "dispatch and the row comparisons of its detector mean anything; 60 s covers it and the 60-s demand average",
    grace_reason="the farm detectors decide on 10 Hz farm samples and recognise an end by a reverse CUSUM or by "
    "the 3P amplitude staying below half its threshold for 3 s (lock-in τ = 1.5 s): several seconds after the "
    "fault is gone; 10 s is that with a margin",
)

HYDRO = ScoringPolicy(
    kind="hydro",
    warmup_s=1.0,
    grace_s=2.0,
    time_base="seconds (one turbine)",
    warmup_reason="the sliding-mode observer starts from zero error states and must reach its sliding surface; "
    "the supervisor applies no correction and its detector takes no decision before 1 s (docs/hydro.md)",
    grace_reason="the offset detector releases a flag after 0.5 s below its threshold and the reconstruction "
    "filter's time constant is 0.05–0.1 s; 2 s leaves room for the pressure transient that the fault's end "
    "excites",
)

POLICIES: dict[str, ScoringPolicy] = {p.kind: p for p in (TURBINE, FARM, HYDRO)}


def farm_policy(turbines: int) -> ScoringPolicy:
    """The farm's policy for a farm of ``turbines`` turbines (``FARM`` is the paper's nine): the time base counts
    each of them."""
    return replace(FARM, time_base=FARM_TIME_BASE.format(n=turbines))


def policy_for(kind: str) -> ScoringPolicy:
    """The scoring policy of a plant kind; a kind without one is refused."""
    try:
        return POLICIES[kind]
    except KeyError:
        raise KeyError(f"no scoring policy for plant kind {kind!r}; known: {', '.join(sorted(POLICIES))}") from None


def policy_table() -> str:
    """The policies as ``docs/scorecards.md`` shows them: a table of the values, then why each is what it is.

    Regenerate that part of the page with ``python -c "from windwarden.evaluation.scoring_policy import
    policy_table; print(policy_table())"`` when a value changes (``tests/test_scoring.py`` compares them)."""
    lines = [
        "| kind | warm-up | grace | false-alarm time base |",
        "|---|---|---|---|",
    ]
    lines += [f"| {p.kind} | {p.warmup_s:g} s | {p.grace_s:g} s | {p.time_base} |" for p in POLICIES.values()]
    lines.append("")
    for p in POLICIES.values():
        lines.append(f"* {p.kind}, warm-up {p.warmup_s:g} s: {p.warmup_reason}.")
        lines.append(f"* {p.kind}, grace {p.grace_s:g} s: {p.grace_reason}.")
    return "\n".join(lines)
