"""The API's limits without a network: the token bucket (against its closed form, on a fake clock), the caps on a
run's faults, the bound that keeps the plant's fault list inside one Zenoh reply, the fault-name rule on the
plant's side, and the access log's rotation."""

from __future__ import annotations

import json

import pytest

from api.accesslog import AccessLogFile
from api.limits import TokenBuckets, cap_problems, retry_after
from api.models import FaultRequest
from api.settings import MAX_INJECTIONS, ApiLimits
from windwarden.live.faults import FaultBook, FaultRecord, InjectionRefusedError
from wwcore.scenario import FaultSpec
from wwcore.wire import MAX_JSON_BYTES, encode_json

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_token_bucket_allows_the_burst_then_the_rate_and_says_how_long_to_wait():
    clock = Clock()
    buckets = TokenBuckets(rate=2.0, burst=5, max_clients=16, clock=clock)
    assert [buckets.take("a") for _ in range(5)] == [0.0] * 5
    assert buckets.take("a") == pytest.approx(0.5)  # one token at 2 per second
    clock.now += 0.25
    assert buckets.take("a") == pytest.approx(0.25)  # a refused request takes nothing
    clock.now += 0.25
    assert buckets.take("a") == 0.0 and buckets.take("a") == pytest.approx(0.5)
    assert buckets.take("b") == 0.0  # per client
    clock.now += 60.0  # refilled to the burst, never beyond
    assert [buckets.take("a") for _ in range(6)].count(0.0) == 5


def test_token_bucket_over_a_long_run_admits_burst_plus_rate_times_time():
    clock = Clock()
    buckets = TokenBuckets(rate=3.0, burst=4, max_clients=16, clock=clock)
    admitted = 0
    for _ in range(10_000):  # a client asking every 10 ms for 100 s
        admitted += buckets.take("x") == 0.0
        clock.now += 0.01
    assert abs(admitted - (4 + 3.0 * 100.0)) <= 1  # burst + rate × time


def test_token_buckets_remember_a_bounded_number_of_clients():
    clock = Clock()
    buckets = TokenBuckets(rate=1.0, burst=1, max_clients=16, clock=clock)
    for i in range(1000):
        buckets.take(f"10.0.{i // 256}.{i % 256}")
    assert len(buckets) == 16
    assert buckets.take("10.0.3.231") > 0.0  # the most recent are kept


def test_retry_after_is_whole_seconds_and_at_least_one():
    assert [retry_after(w) for w in (0.01, 0.5, 1.0, 1.2, 7.9)] == ["1", "1", "1", "2", "8"]


def listed(state: str, turbine: int = 1, source: str = "api") -> dict:
    return {"state": state, "source": source, "fault": {"turbine": turbine}}


def test_caps_count_active_and_pending_faults_per_turbine_and_in_total_and_injections_per_run():
    limits = ApiLimits(api_max_faults_per_turbine=2, api_max_faults=3, api_max_injections=6)
    fault = FaultSpec(target="omega_g_m1", kind="fixed", value=1.0, start_s=0.0, turbine=2)
    assert cap_problems(fault, [listed("active", 2), listed("ended", 2), listed("cancelled", 2)], limits) == []
    per_turbine = cap_problems(fault, [listed("active", 2), listed("pending", 2, "scenario")], limits)
    assert [f for f, _ in per_turbine] == ["turbine"] and "turbine 2 has 2" in per_turbine[0][1]
    assert cap_problems(fault, [listed("active", 1), listed("active", 1)], limits) == []
    total = cap_problems(fault, [listed("active", 1), listed("active", 3), listed("pending", 4)], limits)
    assert len(total) == 1 and "WINDWARDEN_API_MAX_FAULTS=3" in total[0][1]
    history = cap_problems(fault, [listed("ended", 1)] * 6, limits)
    assert [f for f, _ in history] == ["name"] and "WINDWARDEN_API_MAX_INJECTIONS=6" in history[0][1]
    assert cap_problems(fault, [listed("ended", 1, "scenario")] * 6, limits) == []


def test_the_fault_list_at_every_cap_fits_in_one_zenoh_reply():
    """The largest listing the caps allow (every injection with the longest fields, 40 scheduled faults as well)
    is under the wire's limit: ``GET /faults`` keeps working however the API is used."""
    tiny, huge = -1.2345678901234567e-300, 1.2345678901234567e300
    spec = FaultSpec(
        target="t" * 64,
        kind="drivetrain_wear",
        value=tiny,
        start_s=huge,
        end_s=huge * 1.1,
        ramp_s=-tiny,
        omega_n=12.345678901234567,
        zeta=1.2345678901234567,
        turbine=10_000,
        name="n" * 64,
    )
    records = [FaultRecord(spec, "api", cleared_at=huge * 1.05)] * MAX_INJECTIONS
    records += [FaultRecord(spec, "scenario", cleared_at=huge * 1.05)] * 40
    reply = encode_json("plant.faults", {"ok": True, "t": tiny, "faults": [r.to_json(huge) for r in records]})
    assert len(reply) < MAX_JSON_BYTES, f"{len(reply)} bytes"
    with pytest.raises(ValueError):
        ApiLimits(api_max_injections=MAX_INJECTIONS + 1)


@pytest.mark.parametrize(
    "name",
    ["\udcff", "a\x00b", "tab\there", "new\nline", "x" * 65, " leading", "trailing ", "a/b", "50%", "é", "<b>", ""],
    ids=["surrogate", "nul", "tab", "newline", "65-chars", "leading-space", "trailing-space", "slash", "percent",
         "non-ascii", "markup", "empty"],
)  # fmt: skip
def test_bad_names_are_refused_by_the_api_model_and_by_the_plant(name):
    body = {"target": "omega_g_m1", "kind": "fixed", "value": 1.0, "start_s": 0.0, "name": name}
    with pytest.raises(ValueError):
        FaultRequest.model_validate(body)
    book = FaultBook("turbine", 1, 100.0, [])
    with pytest.raises(InjectionRefusedError) as refused:
        book.prepare(FaultSpec.model_validate(body), 1.0)
    field, message = refused.value.problems[0]
    assert field == "name" and (not name or name not in message)  # the message never echoes the name


@pytest.mark.parametrize("name", ["a", "rotor sensor (gain 1.1)", "F5: gen+rot_2.b-c", "x" * 64])
def test_good_names_pass(name):
    body = {"target": "omega_g_m1", "kind": "fixed", "value": 1.0, "start_s": 0.0, "name": name}
    assert FaultRequest.model_validate(body).name == name
    assert FaultBook("turbine", 1, 100.0, []).prepare(FaultSpec.model_validate(body), 1.0).name == name


def test_access_log_rotates_once_it_is_full(tmp_path):
    path = tmp_path / "api-access.jsonl"
    log = AccessLogFile(path, max_bytes=4096)
    for i in range(200):
        log.write({"i": i, "path": "/faults", "pad": "x" * 40})
    log.close()
    kept = path.read_text().splitlines()
    older = (tmp_path / "api-access.jsonl.1").read_text().splitlines()
    assert path.stat().st_size <= 4096 and (tmp_path / "api-access.jsonl.1").stat().st_size <= 4096
    numbers = [json.loads(line)["i"] for line in older + kept]
    assert numbers == list(range(200 - len(numbers), 200))  # the newest lines, in order, none torn
