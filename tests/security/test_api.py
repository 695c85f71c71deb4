"""Hostile HTTP clients against a live system on loopback (issue 22, §3 and §6).

A plant (real time, ×1) and a supervisor run in threads over a Zenoh router on loopback; the API is served by
uvicorn on a real socket with tight limits. Each probe is refused with its code, changes nothing in the plant (its
fault book is compared before and after), and every request is tallied here by the reason it was refused; the last
test checks that ``/metrics`` (``windwarden_api_refused_total``) and the access log in the run folder count exactly
the same, that the plant kept running and that nothing already in ``events.jsonl`` was lost.

Each probe comes from its own loopback address (its own rate-limit bucket) unless it is about the rate limit.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import select
import socket
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from typing import Any

import httpx
import pytest
from uvicorn.protocols.http.flow_control import HIGH_WATER_LIMIT

from api.main import create_app
from api.settings import ACCESS_LOG, ApiSettings
from tests.live.api_server import serve
from tests.live.helpers import LiveNodes, router, scenario, wait_for
from windwarden.live.runfolder import EVENTS

TOKEN = "security-token-9f2c"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
BURST = 6
RATE = 0.05  # per second: a refused client waits 20 s
PER_TURBINE = 3
BODY_CAP = 16_384
BODY_TIMEOUT_S = 2.0
MAX_CONCURRENT = 64
RUN = """
name = "security-api"
duration_s = 900.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0]]
"""
GOOD = {"target": "omega_g_m2", "kind": "fixed", "value": 100.0, "start_s": 700.0, "end_s": 750.0}
REASONS = {401: "unauthorized", 404: "not_found", 405: "method_not_allowed", 408: "body_timeout",
           413: "body_too_large", 422: "invalid", 429: "rate_limited"}  # fmt: skip


def reason_of(status: int, detail: Any) -> str | None:
    """The reason the API counts a response under, read from the response as a client sees it."""
    if status == 409:
        return "fault_cap" if "WINDWARDEN_API_MAX_" in json.dumps(detail) else "conflict"
    if status == 503:
        return "overloaded" if "WINDWARDEN_API_MAX_CONCURRENT" in json.dumps(detail) else None
    return REASONS.get(status)


class Probe:
    """The system under test and a tally of every request sent to it, by the reason it was refused."""

    def __init__(self, base: str, nodes: LiveNodes):
        self.base = base
        self.host, port = base.removeprefix("http://").split(":")
        self.port = int(port)
        self.nodes = nodes
        self.refused: Counter[str] = Counter()
        self.requests = 0
        self._addresses = (f"127.1.{i // 250}.{1 + i % 250}" for i in itertools.count())

    def address(self) -> str:
        return next(self._addresses)

    def client(self, address: str | None = None) -> httpx.Client:
        transport = httpx.HTTPTransport(local_address=address or self.address(), verify=False)
        return httpx.Client(base_url=self.base, transport=transport, timeout=60)

    def count(self, status: int, text: str) -> None:
        self.requests += 1
        try:
            detail = json.loads(text).get("detail")
        except (ValueError, AttributeError):
            detail = None
        reason = reason_of(status, detail)
        if reason is not None:
            self.refused[reason] += 1

    def send(self, method: str, path: str, client: httpx.Client | None = None, **kwargs: Any) -> httpx.Response:
        if client is None:
            with self.client() as fresh:
                response = fresh.request(method, path, **kwargs)
        else:
            response = client.request(method, path, **kwargs)
        self.count(response.status_code, response.text)
        return response

    def raw(self, head: bytes, body: Iterable[bytes] = ()) -> tuple[int, dict[str, str], int]:
        """A request written on a socket: the head, then body pieces until the server answers. Returns the
        status, the response headers and the body bytes sent before the answer came."""
        with socket.create_connection((self.host, self.port), timeout=30, source_address=(self.address(), 0)) as s:
            s.sendall(head)
            sent = 0
            for piece in body:
                if select.select([s], [], [], 0)[0]:
                    break
                try:
                    s.sendall(piece)
                except (BrokenPipeError, ConnectionResetError):
                    break
                sent += len(piece)
            received = b""
            try:
                while chunk := s.recv(65536):
                    received += chunk
            except (ConnectionResetError, TimeoutError):
                pass
        head_text, _, text = received.partition(b"\r\n\r\n")
        lines = head_text.decode("latin-1").split("\r\n")
        status = int(lines[0].split()[1])
        headers = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])}
        self.count(status, text.decode("latin-1"))
        return status, headers, sent

    def plant_book(self) -> list[tuple[str, str, bool, float | None]]:
        return [(r.spec.label, r.source, r.cancelled, r.cleared_at) for r in self.nodes.plant.book.records]


@pytest.fixture(scope="module")
def probe(tmp_path_factory) -> Iterator[Probe]:
    run_dir = tmp_path_factory.mktemp("security-api") / "run"
    with router() as endpoint, LiveNodes(endpoint, scenario(RUN), run_dir, mode="realtime", speed=1.0) as nodes:
        settings = ApiSettings(
            connect=endpoint,
            api_token=TOKEN,
            run_dir=run_dir,
            api_rate_per_s=RATE,
            api_rate_burst=BURST,
            api_max_faults_per_turbine=PER_TURBINE,
            api_max_body_bytes=BODY_CAP,
            api_body_timeout_s=BODY_TIMEOUT_S,
            api_max_concurrent=MAX_CONCURRENT,
        )
        with serve(create_app(settings)) as base:
            p = Probe(base, nodes)
            assert wait_for(lambda: p.send("GET", "/health").json()["plant"], 30)
            assert wait_for(lambda: (run_dir / EVENTS).exists(), 30)
            p.events_at_start = (run_dir / EVENTS).read_text().splitlines()
            yield p


def refused_without_effect(probe: Probe, response: httpx.Response, status: int, field: str | None = None) -> None:
    assert response.status_code == status, response.text
    if field is not None:
        detail = response.json()["detail"]
        assert any(field in map(str, item["loc"]) for item in detail), detail


def post_raw_json(probe: Probe, payload: bytes) -> httpx.Response:
    return probe.send("POST", "/faults", content=payload, headers=AUTH | {"content-type": "application/json"})


# -- bodies ------------------------------------------------------------------------------------------------------
def test_a_declared_50_mb_body_is_refused_before_it_is_sent(probe):
    before = probe.plant_book()
    head = (
        f"POST /faults HTTP/1.1\r\nHost: {probe.host}\r\nAuthorization: Bearer {TOKEN}\r\n"
        "Content-Type: application/json\r\nContent-Length: 50000000\r\n\r\n"
    ).encode()
    status, headers, sent = probe.raw(head)  # not a byte of the body written: the answer comes first
    assert status == 413 and headers["connection"] == "close" and sent == 0
    assert probe.plant_book() == before


def test_a_chunked_body_is_refused_once_it_passes_the_cap(probe):
    before = probe.plant_book()
    head = (
        f"POST /faults HTTP/1.1\r\nHost: {probe.host}\r\nAuthorization: Bearer {TOKEN}\r\n"
        "Content-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n"
    ).encode()
    piece = b"%x\r\n%s\r\n" % (8192, b" " * 8192)
    status, headers, sent = probe.raw(head, itertools.repeat(piece, 50_000_000 // 8192))
    assert status == 413 and headers["connection"] == "close"
    assert sent < 8 * 2**20, f"{sent} bytes went out before the 413 (50 MB offered)"
    assert probe.plant_book() == before


def test_bodies_that_trickle_in_time_out_without_holding_the_api(probe):
    """More clients than the API takes at once each promise a body and stop sending: the API keeps answering
    others meanwhile, and each of them gets 408 once ``WINDWARDEN_API_BODY_TIMEOUT_S`` is up."""
    before = probe.plant_book()
    head = (
        f"POST /faults HTTP/1.1\r\nHost: {probe.host}\r\nAuthorization: Bearer {TOKEN}\r\n"
        'Content-Type: application/json\r\nContent-Length: 1000\r\n\r\n{"target": '
    ).encode()
    sockets = []
    try:
        for _ in range(MAX_CONCURRENT + 6):
            s = socket.create_connection((probe.host, probe.port), timeout=30, source_address=(probe.address(), 0))
            sockets.append(s)
            s.sendall(head)
        started = time.monotonic()
        assert probe.send("GET", "/faults").status_code == 200  # not held up by them
        assert time.monotonic() - started < BODY_TIMEOUT_S
        for s in sockets:
            answer = b""
            while chunk := s.recv(65536):
                answer += chunk
            status = int(answer.split(b" ", 2)[1])
            probe.count(status, answer.partition(b"\r\n\r\n")[2].decode())
            assert status == 408 and b"WINDWARDEN_API_BODY_TIMEOUT_S" in answer, answer[:300]
    finally:
        for s in sockets:
            s.close()
    assert probe.plant_book() == before


@pytest.mark.parametrize(
    "payload",
    [
        b"{not json",
        b'{"target": "omega_g_m2", "kind": "fixed", "value": NaN, "start_s": 0}',
        b'{"target": "omega_g_m2", "kind": "fixed", "value": 1e400, "start_s": 0}',
        b'{"target": "omega_g_m2", "kind": "fixed", "value": 1, "start_s": 0, "turbine": 1' + b"0" * 5000 + b"}",
        b"[" * 5000 + b"]" * 5000,
        b"[1, 2]",
        b"",
        b'"\xff\xfe"',
        b'{"target": "omega_g_m2", "kind": "fixed", "value": 1, "start_s": 0, "target": "omega_g_m1"',
    ],
    ids=["not-json", "nan", "infinity", "5000-digit-integer", "nested-5000-deep", "array", "empty", "not-utf8",
         "truncated"],
)  # fmt: skip
def test_malformed_bodies_get_422(probe, payload):
    before = probe.plant_book()
    refused_without_effect(probe, post_raw_json(probe, payload), 422)
    assert probe.plant_book() == before


# -- names ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "name_json, status",
    [
        (json.dumps("n" * 65), 422),
        (json.dumps("n" * 10_000), 422),
        (json.dumps("n" * 150_000), 413),
        ('"\\udcff"', 422),  # a lone surrogate, as JSON escapes it
        ('"ok\\ud800"', 422),
        ('"\\ud83d\\ude00"', 422),  # a valid pair, but not ASCII
        ('"bell\\u0007"', 422),
        ('"nul\\u0000x"', 422),
        ('"esc\\u001b[31m"', 422),
        ('"line\\nbreak"', 422),
        ('"a/b"', 422),
        ('"50%"', 422),
        ('" lead"', 422),
        ('""', 422),
    ],
    ids=["65-chars", "10-kB", "150-kB", "lone-surrogate", "trailing-surrogate", "emoji", "bell", "nul", "ansi-escape",
         "newline", "slash", "percent", "leading-space", "empty"],
)  # fmt: skip
def test_long_and_invalid_names_are_refused(probe, name_json, status):
    before = probe.plant_book()
    payload = json.dumps(GOOD)[:-1] + f', "name": {name_json}}}'
    response = post_raw_json(probe, payload.encode())
    refused_without_effect(probe, response, status, "name" if status == 422 else None)
    assert len(response.content) < 4096, "the refusal does not echo the name back in full"
    assert probe.plant_book() == before


@pytest.mark.parametrize(
    "label, status",
    # a newline matches no route at all (Starlette's path parameters stop at one): 404
    [("x" * 10_000, 422), ("bad%00label", 422), ("bad%0Alabel", 404), ("%ED%B3%BF", 422), ("\u00e9t\u00e9", 422)],
    ids=["10-kB", "nul", "newline", "surrogate-bytes", "non-ascii"],
)
def test_bad_labels_in_the_path_are_refused(probe, label, status):
    before = probe.plant_book()
    refused_without_effect(probe, probe.send("DELETE", f"/faults/{label}", headers=AUTH), status)
    assert probe.plant_book() == before


def test_a_150_kb_path_is_refused_by_the_http_server_and_the_api_stays_up(probe):
    """Over the server's 16 kB limit on a request's head: answered by uvicorn itself, never reaching the app (so not
    in the access log: see docs/live.md)."""
    with socket.create_connection((probe.host, probe.port), timeout=30) as s:
        s.sendall(b"DELETE /faults/" + b"x" * 150_000 + b" HTTP/1.1\r\nHost: a\r\n\r\n")
        answer = b""
        try:
            while chunk := s.recv(65536):
                answer += chunk
        except ConnectionResetError:
            pass
    assert answer.startswith(b"HTTP/1.1 4"), answer[:200]
    assert probe.send("GET", "/health").status_code == 200


# -- types ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "change, field",
    [
        ({"value": True}, "value"),
        ({"value": "100"}, "value"),
        ({"value": [100.0]}, "value"),
        ({"turbine": "1"}, "turbine"),
        ({"turbine": 1.0}, "turbine"),
        ({"turbine": True}, "turbine"),
        ({"start_s": "700"}, "start_s"),
        ({"end_s": False}, "end_s"),
        ({"kind": 1}, "kind"),
        ({"kind": "FIXED"}, "kind"),
        ({"target": ["omega_g_m2"]}, "target"),
        ({"name": 5}, "name"),
        ({"ramp_s": None}, "ramp_s"),
    ],
    ids=lambda v: json.dumps(v) if isinstance(v, dict) else v,
)
def test_types_are_not_coerced(probe, change, field):
    before = probe.plant_book()
    response = probe.send("POST", "/faults", json=GOOD | change, headers=AUTH)
    refused_without_effect(probe, response, 422, field)
    assert probe.plant_book() == before


# -- the caps and the rate limit -------------------------------------------------------------------------------------
def test_active_faults_per_turbine_are_capped_and_a_cleared_one_frees_its_place(probe):
    with probe.client() as c:
        names = [f"cap probe {i}" for i in range(PER_TURBINE)]
        for name in names:
            assert probe.send("POST", "/faults", c, json=GOOD | {"name": name}, headers=AUTH).status_code == 201
    before = probe.plant_book()
    over = probe.send("POST", "/faults", json=GOOD | {"name": "one too many"}, headers=AUTH)
    refused_without_effect(probe, over, 409, "turbine")
    assert "WINDWARDEN_API_MAX_FAULTS_PER_TURBINE" in over.text
    assert probe.plant_book() == before
    assert probe.send("DELETE", f"/faults/{names[0]}", headers=AUTH).json()["fault"]["state"] == "cancelled"
    assert probe.send("POST", "/faults", json=GOOD | {"name": "in its place"}, headers=AUTH).status_code == 201
    for name in [*names[1:], "in its place"]:
        assert probe.send("DELETE", f"/faults/{name}", headers=AUTH).status_code == 200
    listing = probe.send("GET", "/faults").json()
    assert listing["pending"] == [] and {f["label"] for f in listing["past"]} >= {*names, "in its place"}


def test_a_burst_over_the_rate_limit_gets_429_with_retry_after_per_client(probe):
    before = probe.plant_book()
    with probe.client() as c:
        bad = GOOD | {"value": "x"}  # refused by the schema: the plant is never asked
        statuses = [probe.send("POST", "/faults", c, json=bad, headers=AUTH) for _ in range(BURST + 4)]
    assert [r.status_code for r in statuses] == [422] * BURST + [429] * 4, [r.status_code for r in statuses]
    waits = [int(r.headers["retry-after"]) for r in statuses[BURST:]]
    assert all(1 <= w <= 1 / RATE + 1 for w in waits), waits
    with probe.client() as c:  # a wrong token is rate-limited too: guessing it costs the same
        guesses = [probe.send("POST", "/faults", c, json=GOOD, headers={"Authorization": "Bearer guess"})]
        guesses += [probe.send("DELETE", "/faults/x", c, headers={"Authorization": f"Bearer {i}"}) for i in range(7)]
    assert [r.status_code for r in guesses] == [401] * BURST + [429] * 2
    assert probe.send("POST", "/faults", json=bad, headers=AUTH).status_code == 422  # another client is not limited
    assert probe.plant_book() == before


def test_200_concurrent_requests_each_get_a_valid_answer_and_the_api_stays_up(probe):
    before = probe.plant_book()
    requests = [("GET", "/faults", {})] * 110 + [("GET", "/run", {})] * 30 + [("GET", "/metrics", {})] * 20
    requests += [("POST", "/faults", {"json": GOOD | {"turbine": "1"}, "headers": AUTH})] * 30
    requests += [("POST", "/faults", {"content": b"x" * (BODY_CAP + 1), "headers": AUTH})] * 10

    async def everything() -> list[httpx.Response | BaseException]:
        limits = httpx.Limits(max_connections=len(requests), max_keepalive_connections=0)
        transport = httpx.AsyncHTTPTransport(local_address=probe.address(), verify=False, limits=limits)
        async with httpx.AsyncClient(base_url=probe.base, transport=transport, timeout=120) as client:
            return await asyncio.gather(*(client.request(m, p, **kw) for m, p, kw in requests), return_exceptions=True)

    started = time.monotonic()
    answers = asyncio.run(everything())
    elapsed = time.monotonic() - started
    failures = [a for a in answers if isinstance(a, BaseException)]
    assert not failures, failures[:3]
    got: Counter[tuple[str, str, int]] = Counter()
    for (method, path, _), response in zip(requests, answers, strict=True):
        assert isinstance(response, httpx.Response)
        probe.count(response.status_code, response.text)
        got[(method, path, response.status_code)] += 1
    allowed = {("GET", 200), ("GET", 503), ("POST", 422), ("POST", 413), ("POST", 429), ("POST", 503)}
    assert {(m, s) for m, _, s in got} <= allowed, got
    assert got[("GET", "/faults", 200)] > 0, got
    print(f"\n200 concurrent requests answered in {elapsed:.2f} s: {dict(got)}")
    assert probe.send("GET", "/faults").status_code == 200
    assert probe.send("GET", "/health").json()["plant"]
    assert probe.plant_book() == before


# -- what was counted ----------------------------------------------------------------------------------------------
def test_every_refusal_is_counted_in_metrics_and_in_the_access_log_and_the_plant_kept_going(probe):
    metrics = probe.send("GET", "/metrics").text
    counted = Counter(
        {
            line.split('reason="')[1].split('"')[0]: int(float(line.split()[-1]))
            for line in metrics.splitlines()
            if line.startswith("windwarden_api_refused_total{")
        }
    )
    assert counted == probe.refused, f"metrics {dict(counted)} vs sent {dict(probe.refused)}"
    assert {"body_too_large", "body_timeout", "invalid", "rate_limited", "unauthorized", "fault_cap"} <= set(counted)

    log_path = probe.nodes.run_dir / ACCESS_LOG
    lines = [json.loads(line) for line in log_path.read_text().splitlines()]
    fields = {"time", "client", "method", "path", "route", "status", "bytes", "bytes_in", "duration_ms", "refused"}
    assert all(fields <= set(line) for line in lines)
    assert all(line["client"].startswith("127.") for line in lines)
    logged = Counter(line["refused"] for line in lines if line["refused"] is not None)
    assert logged == probe.refused, f"access log {dict(logged)} vs sent {dict(probe.refused)}"
    assert len(lines) == probe.requests - 1 or len(lines) == probe.requests  # the last line may still be writing
    big = [line for line in lines if line["status"] == 413]
    # the guard stops reading at the first message past the cap; that message holds what uvicorn buffered before it
    # paused reading (its high-water mark) plus the one socket read that crossed the mark (asyncio reads up to
    # ``max_size`` at a time), so no 413 has read more than the cap and those two
    overshoot = HIGH_WATER_LIMIT + asyncio.selector_events._SelectorSocketTransport.max_size
    assert big and all(line["bytes_in"] <= BODY_CAP + overshoot for line in big), [line["bytes_in"] for line in big]

    run = probe.send("GET", "/run").json()
    assert run["state"] == "running" and probe.nodes.error is None
    t0 = run["t"]
    assert wait_for(lambda: probe.send("GET", "/run").json()["t"] > t0, 10), "the plant stopped"
    events = (probe.nodes.run_dir / EVENTS).read_text().splitlines()
    assert events[: len(probe.events_at_start)] == probe.events_at_start, "events.jsonl lost lines"
    # the plant holds only the cap probe's faults, all cancelled before they started: none ever acted
    assert not [e for e in events if '"fault_injected"' in e]
    expected = {f"cap probe {i}" for i in range(PER_TURBINE)} | {"in its place"}
    assert {(label, source, cancelled) for label, source, cancelled, _ in probe.plant_book()} == {
        (label, "api", True) for label in expected
    }
