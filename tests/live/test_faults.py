"""The fault book of a live run: what an injection or a clear does, and what is refused."""

from __future__ import annotations

import pytest

from windwarden.live.faults import FaultBook, InjectionRefusedError, check_injection
from wwcore.scenario import FaultSpec

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)


def spec(**kw) -> FaultSpec:
    base = {"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 0.0}
    return FaultSpec.model_validate(base | kw)


def test_a_start_in_the_past_means_now_and_names_the_label_after_it():
    book = FaultBook("turbine", 1, 100.0, [])
    moved = book.prepare(spec(end_s=50.0), t_now=12.34)
    assert moved.start_s == 12.34 and moved.label == "omega_g_m2:fixed@12.34"


@pytest.mark.parametrize(
    "fault, field",
    [
        (spec(turbine=2), "turbine"),
        (spec(target="omega_x"), "target"),
        (spec(value=1e6), "value"),
        (spec(end_s=5.0), "end_s"),  # ends before now (10 s)
        (spec(start_s=200.0), "start_s"),  # after the run
        (spec(kind="gain", value=None), "value"),
    ],
)
def test_refusals_name_the_field(fault, field):
    with pytest.raises(InjectionRefusedError) as refused:
        check_injection(fault, "turbine", 1, t_now=10.0, duration_s=100.0)
    assert field in [f for f, _ in refused.value.problems]
    assert refused.value.status == 422


def test_non_finite_numbers_are_refused():
    fault = FaultSpec.model_construct(**(spec().model_dump() | {"end_s": float("nan")}))
    with pytest.raises(InjectionRefusedError) as refused:
        check_injection(fault, "turbine", 1, t_now=0.0, duration_s=100.0)
    assert ("end_s", "nan is not a finite number") in refused.value.problems


def test_duplicate_labels_conflict_and_clears_end_or_cancel():
    book = FaultBook("turbine", 1, 100.0, [spec(start_s=30.0, end_s=40.0, name="later")])
    first = book.add(book.prepare(spec(name="now"), 10.0))
    with pytest.raises(InjectionRefusedError) as refused:
        book.prepare(spec(name="now"), 11.0)
    assert refused.value.status == 409
    book.mark_cleared(book.check_clear("now", 15.0), 15.0)
    assert first.state(16.0) == "ended" and first.end_s == 15.0
    book.mark_cleared(book.check_clear("later", 20.0), 20.0)  # before it started: it never acts
    assert book.find("later").state(35.0) == "cancelled"
    assert [f.label for f in book.effective()] == ["now"] and book.effective()[0].end_s == 15.0
    with pytest.raises(InjectionRefusedError) as refused:
        book.check_clear("now", 20.0)
    assert refused.value.status == 409
    with pytest.raises(InjectionRefusedError) as refused:
        book.find("nope")
    assert refused.value.status == 404
