"""Helpers of the sharded-supervisor tests: a farm coordinator and supervisor shards, each in a thread with its own
Zenoh session, connected to the router given per node (so a shard can sit behind another router of a mesh)."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import zenoh

from service.plugins import load_plugins
from tests.live.helpers import LiveNodes, router
from windwarden.kinds import RunInfo, kind_for
from windwarden.live.config import SupervisorSettings
from windwarden.live.coordinator import CoordinatorNode, CoordinatorSettings
from windwarden.live.router import free_port, open_router
from windwarden.live.shard import ShardNode, ShardSettings
from windwarden.live.transport import open_session, zenoh_config
from wwcore.scenario import Scenario
from wwcore.scenario.farm import FARM_DT_S
from wwcore.stepping import run_ticks
from wwcore.wire import FARM_REFS

SHARDED_SHORT = """
name = "farm-sharded-short"
duration_s = 15.0
[plant]
kind = "farm"
wind_case = 2
[plant.demand]
mode = "available_fraction"
fraction = 0.8
update_s = 10.0
[wind]
mean = [[0.0, 10.0], [15.0, 11.0]]
# one fault of each type, in both shards (1-4, 5-9), just after the detector's 10 s warm-up: the flags, the
# dispatch modes (3P cancelled, pitch trim, debris) and every field farm.refs carries cross the shards
[[faults]]
name = "F3 drive train wt4"
target = "drivetrain"
kind = "drivetrain_wear"
value = 5.0
turbine = 4
start_s = 10.5
end_s = 15.0
[[faults]]
name = "F2 pitch misalignment wt7"
target = "pitch_actuator_3"
kind = "offset"
value = 0.3
turbine = 7
start_s = 10.5
end_s = 15.0
[[faults]]
name = "F1 debris wt5"
target = "rotor"
kind = "debris"
value = 0.97
turbine = 5
start_s = 11.0
end_s = 13.5
"""


@dataclass
class OneSupervisor:
    """One ``FarmSupervisor`` over the whole farm, no transport (``windwarden.live.batch``): its events, its
    scorecard and every ``farm.refs`` message it answers with, by (tick, turbine)."""

    events: list
    scorecard: dict
    refs: dict[tuple[int, int], bytes]


def one_supervisor(scn: Scenario, seed: int) -> OneSupervisor:
    kind = kind_for(scn.plant.kind)
    plant = kind.make_plant(scn, seed)
    turbines = kind.turbines(plant)
    supervisor = kind.make_supervisor(RunInfo.of(scn, turbines, plant.dt))
    n_steps = round(scn.duration_s / plant.dt)
    score = kind.score(scn, n_steps, plant.dt)
    events: list = []
    refs: dict[tuple[int, int], bytes] = {}

    def stepped(k: int, frame: object, new: object) -> None:
        records = kind.refs_records(new, supervisor, turbines)
        score.on_refs(k, records)
        refs.update({(k, t): kind.refs.encode(records[i]) for i, t in enumerate(turbines)})

    run_ticks(
        plant,
        supervisor,
        range(n_steps),
        controlled=lambda k, frame: score.on_tick(k, frame, plant),
        stepped=stepped,
        advanced=lambda k: events.extend(plant.drain_events() + supervisor.drain_events()),
    )
    metrics = score.result(list(scn.faults))
    return OneSupervisor(events, kind.scorecard(scn, seed, list(scn.faults), events, metrics), refs)


class RefsListener:
    """Every row of every ``refs/*`` frame on the network, by (tick, turbine), from a session of its own."""

    def __init__(self, endpoint: str):
        self.settings = SupervisorSettings(connect=endpoint)
        self.refs: dict[tuple[int, int], bytes] = {}
        self.repeated = 0

    def _on(self, sample) -> None:
        for record in FARM_REFS.decode_frame(sample.payload.to_bytes()):
            key = (int(record["tick"]), int(record["turbine"]))
            self.repeated += key in self.refs
            self.refs[key] = FARM_REFS.encode(record)  # the row as a frame of one, as ``one_supervisor`` keeps it

    def __enter__(self) -> RefsListener:
        self.session = open_session(self.settings)
        self.sub = self.session.declare_subscriber(self.settings.keys.refs("*"), self._on)
        return self

    def __exit__(self, *exc: object) -> None:
        self.sub.undeclare()
        self.session.close()


assert FARM_DT_S == 0.1


@contextlib.contextmanager
def meshed_routers() -> Iterator[tuple[str, str]]:
    """Two routers on loopback, the second connected to the first: (endpoint of the first, of the second)."""
    first, second = (f"tcp/127.0.0.1:{free_port()}" for _ in range(2))
    settings = SupervisorSettings(listen=second, connect=first, zenoh_mode="router")
    with open_router([first]), zenoh_open(settings):
        yield first, second


@contextlib.contextmanager
def zenoh_open(settings: SupervisorSettings) -> Iterator[zenoh.Session]:
    session = zenoh.open(zenoh_config(settings))
    try:
        yield session
    finally:
        session.close()


class Sharded:
    """A coordinator (on ``coordinator_endpoint``) and one shard per (endpoint, turbines) in ``shards``."""

    def __init__(self, coordinator_endpoint: str, shards: list[tuple[str, tuple[int, ...]]], run_dir: Path):
        self.run_dir = run_dir
        self.coordinator_settings = CoordinatorSettings(connect=coordinator_endpoint, run_dir=run_dir)
        self.shard_specs = shards
        self.errors: list[BaseException] = []
        self.killed: list[ShardNode] = []

    def _run(self, node: object) -> None:
        try:
            node.run()
        except BaseException as error:  # surfaced by the test
            self.errors.append(error)

    def __enter__(self) -> Sharded:
        load_plugins()  # once, here: the registries' first load is not thread-safe (each node is a process in use)
        self._sessions = []
        self._threads = []
        session = open_session(self.coordinator_settings)
        self._sessions.append(session)
        self.coordinator = CoordinatorNode(session, self.coordinator_settings)
        self.shards = []
        for endpoint, turbines in self.shard_specs:
            settings = ShardSettings(connect=endpoint, run_dir=self.run_dir)
            session = open_session(settings)
            self._sessions.append(session)
            self.shards.append(ShardNode(session, settings, turbines))
        for node in (self.coordinator, *self.shards):
            thread = threading.Thread(target=self._run, args=(node,), daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def kill(self, i: int) -> None:
        """Shard ``i`` gone as a killed process is, to the network: its loop stops without a last status (it never
        says it is not ready) and its session closes (its links drop, its subscriptions vanish)."""
        node = self.shards[i]
        node.stop()
        self._threads[1 + i].join(10)
        self._sessions[1 + i].close()
        self.killed.append(node)
        self._sessions[1 + i] = None

    def restart(self, i: int) -> ShardNode:
        """A new shard ``i``, the same turbines, its own new session: a restarted process."""
        endpoint, turbines = self.shard_specs[i]
        settings = ShardSettings(connect=endpoint, run_dir=self.run_dir)
        session = self._sessions[1 + i] = open_session(settings)
        node = self.shards[i] = ShardNode(session, settings, turbines)
        thread = self._threads[1 + i] = threading.Thread(target=self._run, args=(node,), daemon=True)
        thread.start()
        return node

    def __exit__(self, *exc: object) -> None:
        for node in (self.coordinator, *self.shards):
            node.stop()
        for thread in self._threads:
            thread.join(10)
        for node in (*self.shards, self.coordinator):
            if node not in self.killed:
                node.close()
        for session in self._sessions:
            if session is not None:
                session.close()


@contextlib.contextmanager
def sharded_farm(
    scn: Scenario, run_dir: Path, shards: list[tuple[int, ...]], *, mode: str, seed: int
) -> Iterator[tuple[Sharded, LiveNodes]]:
    """A router, a coordinator and one shard per turbine tuple in ``shards`` on it (``Sharded``), and the plant and
    recorder nodes of a run of ``scn`` with no whole-farm supervisor (the shards answer the plant)."""
    with (
        router() as endpoint,
        Sharded(endpoint, [(endpoint, s) for s in shards], run_dir) as sharded,
        LiveNodes(endpoint, scn, run_dir, mode=mode, seed=seed, supervisor=False, supervisor_wait_s=30.0) as nodes,
    ):
        yield sharded, nodes
