"""The live subcommands: ``plant``, ``supervise``, ``api`` (each service alone, what docker compose runs),
``up`` (the whole system on one machine), ``demo`` and ``open``.

Each ``_add_*`` function registers one subcommand (``windwarden.cli.SUBCOMMANDS``). Every option also reads
from the environment with the ``WINDWARDEN_`` prefix (``--connect`` ↔ ``WINDWARDEN_CONNECT``); a flag given on
the command line wins.
"""

from __future__ import annotations

import argparse
import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from windwarden.commands.common import BadInputError, check_supervisor
from windwarden.commands.router import ROUTER_SUBCOMMANDS
from windwarden.live.process import (
    ServiceError,
    apply_nice,
    exit_with_parent,
    on_signals,
    setup_logging,
    zenoh_session,
)
from wwcore.scenario import Scenario, load_scenario

log = logging.getLogger("windwarden.live")


def truncated(scenario: Scenario, duration_s: float | None) -> Scenario:
    """The scenario cut to ``duration_s`` (faults that would start after the end are left out)."""
    if duration_s is None or duration_s >= scenario.duration_s:
        return scenario
    faults = [f for f in scenario.faults if f.start_s < duration_s]
    return scenario.model_copy(update={"duration_s": duration_s, "faults": faults})


def _zenoh_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("zenoh")
    g.add_argument("--connect", default=None, help="endpoints to connect to, comma-separated (tcp/127.0.0.1:7447)")
    g.add_argument("--listen", default=None, help="endpoints to listen on, comma-separated")
    g.add_argument("--zenoh-mode", default=None, choices=["client", "peer", "router"], help="session mode")
    g.add_argument("--farm", default=None, help="farm id: windwarden/<farm>/… (default 'default')")


def _run_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("run folder")
    g.add_argument("--runs-root", type=Path, default=None, help="folder of run folders (default runs)")
    g.add_argument("--run-id", default=None, help="run id (default: time-scenario-random)")
    g.add_argument("--run-dir", type=Path, default=None, help="the run folder itself")
    g.add_argument("--rerun-url", default=None, help="Rerun gRPC proxy, rerun+http://127.0.0.1:9876/proxy")


def _flags(args: argparse.Namespace, names: list[str]) -> dict[str, Any]:
    return {name: getattr(args, name, None) for name in names}


ZENOH_FLAGS = ["connect", "listen", "zenoh_mode", "farm"]
RUN_FLAGS = ["runs_root", "run_id", "run_dir", "rerun_url"]


# -- plant ---------------------------------------------------------------------------------------------------------
def _add_plant(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plant", help="run the plant simulator as a Zenoh service (one run of a scenario)")
    p.add_argument("scenario", nargs="?", default=None, help="shipped scenario or file (WINDWARDEN_SCENARIO)")
    p.add_argument("--seed", type=int, default=None, help="master seed; run 0 of `windwarden eval --seed`")
    p.add_argument("--mode", choices=["realtime", "lockstep"], default=None, help="timing mode (default realtime)")
    p.add_argument("--speed", type=float, default=None, help="realtime speed-up ×k (default 1)")
    p.add_argument("--duration", dest="duration_s", type=float, default=None, help="s, stop before the scenario's end")
    p.add_argument(
        "--supervisor-wait",
        dest="supervisor_wait_s",
        type=float,
        default=None,
        help="s to wait for a supervisor before tick 0 (default 60)",
    )
    _zenoh_flags(p)
    _run_flags(p)
    p.set_defaults(func=cmd_plant)


def service_errors(command: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """A service that cannot start says why on stderr and exits 1."""

    def run(args: argparse.Namespace) -> int:
        try:
            return command(args)
        except ServiceError as error:
            log.error("%s", error)
            return 1

    return run


@service_errors
def cmd_plant(args: argparse.Namespace) -> int:
    from windwarden.live.config import PlantSettings, new_run_id, settings_from_flags
    from windwarden.live.finalize import finalize_scorecard
    from windwarden.live.plant_node import PlantNode

    setup_logging("plant")
    try:
        settings = settings_from_flags(
            PlantSettings,
            _flags(
                args, ["scenario", "seed", "mode", "speed", "duration_s", "supervisor_wait_s", *ZENOH_FLAGS, *RUN_FLAGS]
            ),
        )
    except ValueError as error:
        raise BadInputError(str(error)) from None
    scenario = truncated(load_scenario(settings.scenario), settings.duration_s)
    check_kind(scenario.plant.kind)
    check_supervisor(scenario)  # the supervisor would refuse these options: say so before the run starts
    apply_nice(settings)
    run_id = settings.run_id or new_run_id(scenario.name)
    run_dir = settings.folder(run_id)
    display = None
    if settings.rerun_url:
        from dashboards.live import LiveRecording

        display = LiveRecording(
            scenario.plant.kind,
            "plant",
            run_id,
            settings.rerun_url,
            n_turbines=scenario.plant.n_turbines,
            plant_section=scenario.plant,
        )
    with zenoh_session(settings) as session:
        node = PlantNode(session, settings, scenario, run_id, run_dir, display)
        on_signals(node.stop)
        exit_with_parent(node.stop)
        log.info("run %s: %s, %s ×%g, folder %s", run_id, scenario.name, settings.mode, settings.speed, run_dir)
        try:
            code = node.run()
        finally:
            node.close()
    finalize_scorecard(run_dir)
    log.info("run %s ended; scorecard in %s", run_id, run_dir)
    return code


def check_kind(kind: str) -> None:
    from windwarden.kinds import KINDS

    if kind not in KINDS:
        raise BadInputError(f"the live system does not run {kind!r} plants yet (it runs: {', '.join(KINDS)})")


# -- supervise -----------------------------------------------------------------------------------------------------
def _plant_wait_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--plant-wait",
        dest="plant_wait_s",
        type=float,
        default=None,
        help="s to wait for a plant; 0 (default) waits for ever",
    )


def _add_supervise(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("supervise", help="run the supervisor as a Zenoh service (serves whatever plant runs)")
    _plant_wait_flag(p)
    p.add_argument("--exit-with-run", action="store_true", default=None, help="exit when the plant's run ends")
    p.add_argument(
        "--turbines",
        default=None,
        help="farm only: run a supervisor shard that owns these turbines (1-40, 1,3,5-9) beside `windwarden "
        "coordinate` (docs/live.md, 'Sharded farm supervisor')",
    )
    p.add_argument(
        "--coordinator-timeout",
        dest="coordinator_timeout_s",
        type=float,
        default=None,
        help="shard: s to wait for the coordinator's references of a farm sample (default 2)",
    )
    _zenoh_flags(p)
    _run_flags(p)
    p.set_defaults(func=cmd_supervise)


@service_errors
def cmd_supervise(args: argparse.Namespace) -> int:
    from service.plugins import AlgorithmOptionError, UnknownAlgorithmError
    from windwarden.live.config import SupervisorSettings, settings_from_flags
    from windwarden.live.supervisor_node import SupervisorNode

    if args.turbines is not None or args.coordinator_timeout_s is not None:
        return _supervise_shard(args)
    setup_logging("supervisor")
    try:
        settings = settings_from_flags(
            SupervisorSettings, _flags(args, ["plant_wait_s", "exit_with_run", *ZENOH_FLAGS, *RUN_FLAGS])
        )
    except ValueError as error:
        raise BadInputError(str(error)) from None
    apply_nice(settings)
    factory = None
    if settings.rerun_url:
        from dashboards.live import LiveRecording

        def factory(info: Any) -> Any:
            return LiveRecording(
                info.kind,
                "supervisor",
                info.recording_id or info.run_id,
                settings.rerun_url,
                n_turbines=len(set(info.turbines)),
            )

    with zenoh_session(settings) as session:
        node = SupervisorNode(session, settings, factory)
        on_signals(node.stop)
        exit_with_parent(node.stop)
        try:
            return node.run()
        except (AlgorithmOptionError, UnknownAlgorithmError) as error:  # the plant's run names options we refuse
            raise BadInputError(f"the run's supervisor: {error}") from None
        finally:
            status = node.status()
            log.info(
                "supervisor stops: %d frames, %d gaps, %d observer restarts, dropped %s, step %s",
                status["frames"],
                status["gaps"],
                status["observer_restarts"],
                status["dropped"],
                status["step"],
            )
            node.close()


def _supervise_shard(args: argparse.Namespace) -> int:
    """``supervise --turbines``: a supervisor shard (``windwarden.live.shard``)."""
    from service.farm.shard import ShardingError, parse_turbines
    from service.plugins import AlgorithmOptionError, UnknownAlgorithmError
    from windwarden.live.config import settings_from_flags
    from windwarden.live.shard import ShardNode, ShardSettings

    setup_logging("shard")
    flags = ["plant_wait_s", "turbines", "coordinator_timeout_s", *ZENOH_FLAGS, *RUN_FLAGS]
    try:
        settings = settings_from_flags(ShardSettings, _flags(args, flags))
        turbines = parse_turbines(settings.turbines)
    except ValueError as error:  # ShardingError is one
        raise BadInputError(f"--turbines: {error}" if "turbines" in str(error) else str(error)) from None
    apply_nice(settings)
    with zenoh_session(settings) as session:
        node = ShardNode(session, settings, turbines)
        on_signals(node.stop)
        exit_with_parent(node.stop)
        log.info("supervisor shard %s: turbines %s", node.name, ", ".join(map(str, turbines)))
        try:
            return node.run()
        except (AlgorithmOptionError, UnknownAlgorithmError, ShardingError) as error:
            raise BadInputError(f"the run's supervisor: {error}") from None
        except ValueError as error:  # not a farm
            raise BadInputError(str(error)) from None
        finally:
            status = node.status()
            log.info(
                "shard %s stops: %d frames, %d coordinator timeouts, dropped %s, step %s, coordinator wait %s",
                node.name,
                status["frames"],
                status["coordinator_timeouts"],
                status["dropped"],
                status["step"],
                status["coordinator_wait"],
            )
            node.close()


# -- coordinate ----------------------------------------------------------------------------------------------------
def _add_coordinate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "coordinate",
        help="run the farm coordinator of a sharded supervisor (dispatch and farm decisions; shards: supervise "
        "--turbines)",
    )
    _plant_wait_flag(p)
    p.add_argument(
        "--shard-lost-samples",
        dest="shard_lost_samples",
        type=int,
        default=None,
        help="a shard whose summaries miss this many farm samples (10 Hz) the others summarised is lost: its "
        "turbines are held (2-600, default 10)",
    )
    p.add_argument(
        "--shard-silent",
        dest="shard_silent_s",
        type=float,
        default=None,
        help="s without a shard's status before it is lost (1-60, default 3)",
    )
    _zenoh_flags(p)
    _run_flags(p)
    p.set_defaults(func=cmd_coordinate)


@service_errors
def cmd_coordinate(args: argparse.Namespace) -> int:
    from service.farm.shard import ShardingError
    from service.plugins import AlgorithmOptionError, UnknownAlgorithmError
    from windwarden.live.config import settings_from_flags
    from windwarden.live.coordinator import CoordinatorNode, CoordinatorSettings

    setup_logging("coordinator")
    flags = ["plant_wait_s", "shard_lost_samples", "shard_silent_s", *ZENOH_FLAGS, *RUN_FLAGS]
    try:
        settings = settings_from_flags(CoordinatorSettings, _flags(args, flags))
    except ValueError as error:
        raise BadInputError(str(error)) from None
    apply_nice(settings)
    with zenoh_session(settings) as session:
        node = CoordinatorNode(session, settings)
        on_signals(node.stop)
        exit_with_parent(node.stop)
        try:
            return node.run()
        except (AlgorithmOptionError, UnknownAlgorithmError, ShardingError) as error:
            raise BadInputError(f"the run's supervisor: {error}") from None
        except ValueError as error:  # not a farm
            raise BadInputError(str(error)) from None
        finally:
            status = node.status()
            log.info(
                "coordinator stops: %d farm samples, %d shards lost, %d rejoined, dropped %s, step %s",
                status["samples"],
                status["shards_lost"],
                status["shards_rejoined"],
                status["dropped"],
                status["step"],
            )
            node.close()


# -- api -----------------------------------------------------------------------------------------------------------
def _add_api(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("api", help="serve the REST API (needs WINDWARDEN_API_TOKEN for the mutating routes)")
    p.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=None, help="port (default 8000)")
    _zenoh_flags(p)
    _run_flags(p)
    p.set_defaults(func=cmd_api)


def cmd_api(args: argparse.Namespace) -> int:
    import uvicorn

    from api.main import create_app
    from api.settings import ApiSettings
    from windwarden.live.config import settings_from_flags

    setup_logging("api")
    try:
        settings = settings_from_flags(ApiSettings, _flags(args, ["host", "port", *ZENOH_FLAGS, *RUN_FLAGS]))
    except ValueError as error:
        raise BadInputError(str(error)) from None
    if settings.api_token is None or not settings.api_token.get_secret_value():
        raise BadInputError("set WINDWARDEN_API_TOKEN: the mutating routes need a bearer token")
    server = uvicorn.Server(
        uvicorn.Config(
            create_app(settings),
            host=settings.host,
            port=settings.port,
            log_level="warning",
            access_log=False,
            lifespan="on",
        )
    )

    def stop() -> None:
        server.should_exit = True

    exit_with_parent(stop)
    server.run()
    return 0


# -- up, demo, open ------------------------------------------------------------------------------------------------
def _add_up(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("up", help="run the whole system on this machine: router, plant, supervisor, API, recording")
    p.add_argument("scenario", nargs="?", default="demo", help="shipped scenario or file (default demo)")
    _up_flags(p, viewer="none")
    p.set_defaults(func=cmd_up)


def _up_flags(p: argparse.ArgumentParser, viewer: str) -> None:
    p.add_argument("--mode", choices=["realtime", "lockstep"], default="realtime", help="timing mode")
    p.add_argument("--speed", type=float, default=1.0, help="realtime speed-up ×k (default 1)")
    p.add_argument("--seed", type=int, default=0, help="master seed (default 0)")
    p.add_argument("--duration", type=float, default=None, help="s, stop before the scenario's end")
    p.add_argument("--connect", default=None, help="use this Zenoh router instead of an embedded one")
    p.add_argument("--listen", default=None, help="the embedded router's endpoint (default tcp/127.0.0.1:7447)")
    p.add_argument("--farm", default="default", help="farm id")
    p.add_argument("--api-host", default="127.0.0.1", help="address the API binds (default 127.0.0.1)")
    p.add_argument("--api-port", type=int, default=None, help="API port (default 8000, or a free one)")
    p.add_argument("--no-api", action="store_true", help="do not start the API")
    p.add_argument(
        "--viewer",
        choices=["none", "web", "spawn"],
        default=viewer,
        help=f"Rerun viewer: web serves the web viewer, spawn opens the native one (default {viewer})",
    )
    p.add_argument("--runs-root", type=Path, default=Path("runs"), help="folder of run folders (default runs)")
    p.add_argument("--run-id", default=None, help="run id (default: time-scenario-random)")
    p.add_argument("--no-restart", action="store_true", help="do not restart a supervisor or API that dies")
    p.add_argument(
        "--nice",
        type=int,
        default=None,
        help="niceness of plant and supervisor, e.g. -10 on a busy machine (needs CAP_SYS_NICE)",
    )
    p.add_argument("--quiet", action="store_true", help="no event feed")
    p.add_argument(
        "--shards",
        type=int,
        default=0,
        help="farm: a sharded supervisor, this many shards (supervise --turbines) and a coordinator (default 0: one "
        "supervisor)",
    )
    g = p.add_argument_group("access control")
    g.add_argument(
        "--credentials",
        type=Path,
        default=None,
        help="a folder of <role>.password files (and zenoh-users.txt) to use (default: new ones for this run)",
    )
    g.add_argument("--no-acl", action="store_true", help="the router lets anyone do anything (development)")
    g.add_argument("--no-router-audit", action="store_true", help="do not count what the router refuses")


def cmd_up(args: argparse.Namespace) -> int:
    from windwarden.live.up import Up, UpOptions

    setup_logging("up")
    scenario = truncated(load_scenario(args.scenario), args.duration)
    check_kind(scenario.plant.kind)
    check_supervisor(scenario)
    if not args.speed > 0:
        raise BadInputError(f"--speed must be > 0, got {args.speed}")
    if args.shards:
        check_shards(scenario, args.shards)
    options = UpOptions(
        scenario=scenario,
        mode=args.mode,
        speed=args.speed,
        seed=args.seed,
        connect=args.connect,
        listen=args.listen,
        farm=args.farm,
        api=not args.no_api,
        api_host=args.api_host,
        api_port=args.api_port,
        viewer=args.viewer,
        runs_root=args.runs_root,
        run_id=args.run_id,
        restart=not args.no_restart,
        quiet=args.quiet,
        nice=args.nice,
        acl=not args.no_acl,
        credentials=args.credentials,
        router_audit=not args.no_router_audit,
        shards=args.shards,
    )
    return Up(options).run()


def check_shards(scenario: Scenario, shards: int) -> None:
    """``up --shards``: a farm, a per-turbine detector, 1 … N shards; ``BadInputError`` naming what is not."""
    from service.farm.shard import ShardingError, shard_ranges, shardable

    if scenario.plant.kind != "farm":
        raise BadInputError(f"--shards: only a farm's supervisor is sharded, not a {scenario.plant.kind}'s")
    try:
        shard_ranges(scenario.plant.n_turbines, shards)
        shardable(scenario.supervisor.detector or "analytic")
    except ShardingError as error:
        raise BadInputError(f"--shards: {error}") from None


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="`up` on the shipped demo scenario with the web viewer (what `make demo` runs)")
    p.add_argument("scenario", nargs="?", default="demo", help=argparse.SUPPRESS)
    _up_flags(p, viewer="web")
    p.set_defaults(func=cmd_up)


def _add_finalize(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "finalize",
        help="rescore an ended run from its folder (partial if the plant was killed) and close its recording",
    )
    p.add_argument("run_dir", type=Path, help="the run folder (runs/<run-id>)")
    p.set_defaults(func=cmd_finalize)


def cmd_finalize(args: argparse.Namespace) -> int:
    """``scorecard.json`` from the run's files (``finalize.finalize_scorecard``); the recording compacted and given
    its footer if it has none yet (run it on a run that has ended: the recorder must not be writing)."""
    from rich.console import Console

    from windwarden.live.finalize import finalize_recording, finalize_scorecard, verify_recording
    from windwarden.live.runfolder import RECORDING

    console = Console(highlight=False)
    if not args.run_dir.is_dir():
        raise BadInputError(f"no run folder at {args.run_dir}")
    card = finalize_scorecard(args.run_dir)
    if card is None:
        raise BadInputError(f"{args.run_dir} holds no run (no run.json and scenario.toml from a plant)")
    live = card["live"]
    state = "completed" if live["completed"] else ("partial" if live["partial"] else "stopped early")
    console.print(f"scorecard.json: {state}, {live['scored_s']:g} s scored, {live['events']} events")
    recording = args.run_dir / RECORDING
    if recording.exists():
        verified = verify_recording(recording) or finalize_recording(args.run_dir)
        console.print(f"{RECORDING}: {'verified' if verified else 'does NOT verify'}")
    return 0


def _add_open(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("open", help="open a run's recording in the Rerun viewer")
    p.add_argument("path", type=Path, help="a run folder or an .rrd file")
    p.set_defaults(func=cmd_open)


def cmd_open(args: argparse.Namespace) -> int:
    from windwarden.live.finalize import rerun_binary
    from windwarden.live.runfolder import RECORDING

    path = args.path / RECORDING if args.path.is_dir() else args.path
    if not path.exists():
        raise BadInputError(f"no recording at {path}")
    os.execv(rerun_binary(), [rerun_binary(), str(path)])
    return 0  # not reached


# -- probe (container health checks) -------------------------------------------------------------------------------
def _add_probe(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("probe", help="health check: exit 0 if the service answers (for docker compose)")
    p.add_argument("service", choices=["plant", "supervisor", "api", "router"], help="what to ask")
    p.add_argument("--timeout", type=float, default=3.0, help="s to wait for the answer")
    p.add_argument("--url", default=None, help="api: the health URL (default http://127.0.0.1:$WINDWARDEN_PORT/health)")
    _zenoh_flags(p)
    p.set_defaults(func=cmd_probe)


def cmd_probe(args: argparse.Namespace) -> int:
    """Plant and supervisor: their liveliness token is on the router (asked with whatever role's credentials the
    container has: every role may ask liveliness, only the API may query the status queryables). API: GET /health
    is 200. Router: its endpoint accepts TCP connections."""
    from windwarden.live.config import ApiSettings, ZenohSettings, settings_from_flags
    from windwarden.live.router import DEFAULT_PORT, wait_listening

    if args.service == "api":
        import urllib.request

        url = args.url or f"http://127.0.0.1:{ApiSettings().port}/health"
        try:
            with urllib.request.urlopen(url, timeout=args.timeout) as response:
                return 0 if response.status == 200 else 1
        except OSError:
            return 1
    settings = settings_from_flags(ZenohSettings, _flags(args, ZENOH_FLAGS))
    if args.service == "router":
        endpoint = (settings.listen_endpoints or [f"tcp/127.0.0.1:{DEFAULT_PORT}"])[0].replace("0.0.0.0", "127.0.0.1")
        return 0 if wait_listening(endpoint, args.timeout) else 1
    settings = settings.model_copy(update={"connect_timeout_s": args.timeout})
    try:
        with zenoh_session(settings) as session:
            replies = session.liveliness().get(settings.keys.alive(args.service), timeout=args.timeout)
            return 0 if any(reply.ok is not None for reply in replies) else 1
    except (ServiceError, ValueError, OSError):
        return 1


LIVE_SUBCOMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_plant,
    _add_supervise,
    _add_coordinate,
    _add_api,
    _add_up,
    _add_probe,
    _add_demo,
    _add_open,
    _add_finalize,
    *ROUTER_SUBCOMMANDS,
]
