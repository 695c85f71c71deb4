"""``windwarden up``: the whole system on one machine, no Docker.

One process (this one) starts the Zenoh router (``windwarden router``, with access control: a new password per
role for each run, in ``runs/<id>/secrets/`` with mode 0600; or connects to an existing router), the Rerun
recorder (and a viewer on request), then the API, the supervisor and the plant as child processes of
``windwarden`` with their settings in ``WINDWARDEN_*`` variables (a role's password by file path, never its value),
each in its own session with its output in ``runs/<id>/logs/``. It prints the events as they happen, restarts the
supervisor or the API if one dies (``--restart``), and shuts everything down in order at the scenario's end, on
Ctrl-C or SIGTERM: plant, supervisor, API, the recorder, then the router; finally it recomputes the scorecard from
``events.jsonl`` (partial if the plant was killed) and closes the recording. If ``up`` itself is killed, nothing is
orphaned: the services get SIGTERM from the kernel (``cli.exit_with_parent``) and the watchdog (``watchdog``,
started first, in its own session) stops every child, Rerun's and the router included, and closes the run as
``up`` would have.

Exit code: 0 when the scenario ran to its end and no child failed; 1 when a child failed (even if restarted);
130 on Ctrl-C.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.console import Console

from service.farm.shard import shard_ranges
from windwarden.kinds import kind_for
from windwarden.live.access import USERS_FILE, new_passwords, password_file, write_credentials
from windwarden.live.config import ZenohSettings, new_run_id
from windwarden.live.finalize import finalize_recording, finalize_scorecard, verify_recording
from windwarden.live.recorder import recorder_command
from windwarden.live.recorder import start as start_rerun
from windwarden.live.recorder import stop as stop_rerun
from windwarden.live.router import (
    DEFAULT_PORT,
    RouterAccess,
    free_port,
    read_audit,
    start_router_process,
    wait_listening,
)
from windwarden.live.runfolder import EVENTS, RECORDING, SCENARIO, SCORECARD, write_json
from windwarden.live.status_line import StatusDisplay
from windwarden.live.transport import open_session
from windwarden.live.watchdog import WatchdogLink
from wwcore.events import Event, EventType
from wwcore.keys import KeyTree
from wwcore.scenario import Scenario, dump_scenario
from wwcore.wire import WireError, decode_json

console = Console(stderr=True, highlight=False, soft_wrap=True)
STOP_TIMEOUT_S = 15.0
ROUTER_START_S = 30.0  # s for the router process to listen
SECRETS = "secrets"  # the run's credentials, in the run folder
ROUTER_AUDIT = "router.json"  # what the router refused (counts)
MAX_RESTARTS = 3


@dataclass
class UpOptions:
    scenario: Scenario
    mode: str = "realtime"
    speed: float = 1.0
    seed: int = 0
    connect: str | None = None  # an existing router; None embeds one
    listen: str | None = None  # the embedded router's endpoint; None: tcp/127.0.0.1:7447 or a free port
    farm: str = "default"
    api: bool = True
    api_host: str = "127.0.0.1"
    api_port: int | None = None  # None: 8000 if free, else a free port
    viewer: str = "none"  # none | web | spawn
    runs_root: Path = Path("runs")
    run_id: str | None = None
    restart: bool = True
    quiet: bool = False
    nice: int | None = None  # niceness of plant and supervisor (WINDWARDEN_NICE)
    acl: bool = True  # the router enforces access control (a new password per role for this run)
    credentials: Path | None = None  # a folder of <role>.password (and zenoh-users.txt) to use instead
    router_audit: bool = True  # the router counts what it refuses (runs/<id>/router.json)
    shards: int = 0  # farm: a sharded supervisor, this many shards and a coordinator (0: one supervisor)


@dataclass
class Child:
    name: str
    argv: list[str]
    env: dict[str, str]
    log: Path
    restartable: bool
    nice: int = 0  # niceness added to the child: the real-time pair (plant, supervisor) keeps the CPU first
    proc: subprocess.Popen | None = None
    restarts: int = 0
    failed: bool = False
    started_at: list[float] = field(default_factory=list)

    def start(self) -> None:
        out = self.log.open("ab")
        self.proc = subprocess.Popen(
            self.argv,
            env=self.env,
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        out.close()
        lower_priority(self.proc.pid, self.nice)
        self.started_at.append(time.time())

    def stop(self, timeout: float = STOP_TIMEOUT_S) -> int | None:
        if self.proc is None or self.proc.poll() is not None:
            return None if self.proc is None else self.proc.returncode
        self.proc.terminate()
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait(5.0)


def lower_priority(pid: int, nice: int) -> None:
    """Raise a child's niceness (allowed without privileges); the plant and supervisor stay at 0."""
    if nice > 0:
        with contextlib.suppress(OSError):
            os.setpriority(os.PRIO_PROCESS, pid, os.getpriority(os.PRIO_PROCESS, pid) + nice)


def _port_free(port: int, host: str = "127.0.0.1") -> bool:
    import socket

    with socket.socket() as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def _wait_http(url: str, timeout: float, alive: Any) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if alive() is not None:
            return False
        try:
            with urllib.request.urlopen(url, timeout=1.0) as response:
                if response.status == 200:
                    return True
        except (urllib.error.URLError, ConnectionError, TimeoutError):
            pass
        time.sleep(0.1)
    return False


class Up:
    def __init__(self, options: UpOptions):
        self.o = options
        self.scenario = options.scenario
        self.run_id = options.run_id or new_run_id(self.scenario.name)
        self.run_dir = options.runs_root / self.run_id
        self.logs = self.run_dir / "logs"
        self.children: list[Child] = []
        self.rerun: list[subprocess.Popen] = []
        self.interrupted = threading.Event()
        self.token = os.environ.get("WINDWARDEN_API_TOKEN") or secrets.token_urlsafe(24)
        self.secrets: Path | None = None  # the folder of role credentials (None: no access control)
        self.router: subprocess.Popen | None = None
        self.info: dict[str, Any] = {}
        self.watchdog: WatchdogLink | None = None
        self.pids: dict[str, int] = {}  # every child as started last: in up.json, for the watchdog and for tests
        self.status = StatusDisplay(console)  # the one-line run status (``status_line``)

    def _started(self, name: str, pid: int) -> None:
        self.pids[name] = pid
        if self.watchdog is not None:
            self.watchdog.child(name, pid)
        if self.info:
            write_json(self.run_dir / "up.json", self.info | {"pids": self.pids})

    # -- set-up ---------------------------------------------------------------------------------------------------
    def _endpoint(self) -> str:
        if self.o.connect:
            return self.o.connect
        if self.o.listen:
            return self.o.listen
        port = DEFAULT_PORT if _port_free(DEFAULT_PORT) else free_port()
        return f"tcp/127.0.0.1:{port}"

    def _credentials(self) -> Path | None:
        """The role credentials: the given folder, or new ones for this run in the run folder (0700, files 0600);
        None for an open embedded router (``--no-acl``: a client with credentials cannot join a router without a
        users file) or an existing router (``--connect``) without ``--credentials``."""
        if self.o.connect:
            return self.o.credentials.resolve() if self.o.credentials is not None else None
        if not self.o.acl:
            return None
        if self.o.credentials is not None:
            return self.o.credentials.resolve()
        return write_credentials(self.run_dir / SECRETS, new_passwords()).parent.resolve()

    def _role_env(self, role: str) -> dict[str, str]:
        """How a child proves its role: user name and the path of its password file (never the password)."""
        if self.secrets is None:
            return {}
        return {"WINDWARDEN_ZENOH_USER": role, "WINDWARDEN_ZENOH_PASSWORD_FILE": str(password_file(self.secrets, role))}

    def _start_router(self, endpoint: str) -> subprocess.Popen:
        access = RouterAccess(self.secrets / USERS_FILE, farm=self.o.farm) if self.secrets else None
        env = {k: v for k, v in os.environ.items() if not k.startswith("WINDWARDEN_")}
        env |= {"WINDWARDEN_PARENT_PID": str(os.getpid()), "PYTHONUNBUFFERED": "1"}
        audit = self.run_dir / ROUTER_AUDIT if self.o.router_audit else None
        proc = start_router_process(endpoint, access, self.logs / "router.log", audit, env)
        if not wait_listening(endpoint, ROUTER_START_S, proc.poll):
            stop_rerun(proc, 5.0)
            raise RuntimeError(f"the Zenoh router did not start on {endpoint}; see {self.logs / 'router.log'}")
        return proc

    def _stop_router(self) -> None:
        if self.router is not None and self.router.poll() is None:
            stop_rerun(self.router, STOP_TIMEOUT_S)

    def _child(self, name: str, args: list[str], env: dict[str, str], restartable: bool, nice: int = 0) -> Child:
        argv = [sys.executable, "-m", "windwarden.cli", *args]
        return Child(name, argv, env, self.logs / f"{name}.log", restartable, nice)

    def _env(self, endpoint: str, rerun_url: str) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if not k.startswith("WINDWARDEN_")}
        env |= {
            "WINDWARDEN_CONNECT": endpoint,
            "WINDWARDEN_ZENOH_MODE": "client",
            "WINDWARDEN_FARM": self.o.farm,
            "WINDWARDEN_RUNS_ROOT": str(self.o.runs_root),
            "WINDWARDEN_RUN_ID": self.run_id,
            "WINDWARDEN_RERUN_URL": rerun_url,
            "PYTHONUNBUFFERED": "1",
            "WINDWARDEN_PARENT_PID": str(os.getpid()),  # the services stop if `up` dies (cli.exit_with_parent)
        }
        if "WINDWARDEN_LOG_LEVEL" in os.environ:
            env["WINDWARDEN_LOG_LEVEL"] = os.environ["WINDWARDEN_LOG_LEVEL"]
        return env

    def run(self) -> int:
        self.logs.mkdir(parents=True, exist_ok=True)
        (self.run_dir / SCENARIO).write_text(dump_scenario(self.scenario))
        self.secrets = self._credentials()
        self.watchdog = WatchdogLink(self.run_dir, self.logs / "watchdog.log")
        endpoint = self._endpoint()
        try:
            self.router = None if self.o.connect else self._start_router(endpoint)
            if self.router is not None:
                self._started("router", self.router.pid)
        except (RuntimeError, OSError, ValueError) as error:
            console.print(f"[red]{error}[/red]")
            self.watchdog.done()
            return 1
        try:
            code = self._run(endpoint, self.router)
        finally:
            self._stop_router()
        self.watchdog.done()
        return code

    def _run(self, endpoint: str, router: Any) -> int:
        o = self.o
        rec = recorder_command(self.run_dir / RECORDING, o.viewer)
        self.rerun.append(start_rerun(rec.recorder, self.logs / "recorder.log"))
        self._started("recorder", self.rerun[-1].pid)
        if rec.viewer is not None:
            self.rerun.append(start_rerun(rec.viewer, self.logs / "viewer.log"))
            self._started("viewer", self.rerun[-1].pid)
        for proc in self.rerun:
            lower_priority(proc.pid, 10)
        env = self._env(endpoint, rec.url)
        api_port = o.api_port or (8000 if _port_free(8000, o.api_host) else free_port(o.api_host))
        api_url = f"http://{o.api_host}:{api_port}"
        scenario_file = str(self.run_dir / SCENARIO)
        if o.api:
            api_env = env | self._role_env("api")
            api_env |= {"WINDWARDEN_API_TOKEN": self.token, "WINDWARDEN_RUN_DIR": str(self.run_dir)}
            self.children.append(
                self._child("api", ["api", "--host", o.api_host, "--port", str(api_port)], api_env, True, nice=5)
            )
        rt_env = env | ({"WINDWARDEN_NICE": str(o.nice)} if o.nice is not None else {})
        supervisor_env = rt_env | self._role_env("supervisor")
        if o.shards:  # the coordinator and the shards log in as the supervisor role (docs/live.md)
            self.children.append(self._child("coordinator", ["coordinate"], supervisor_env, True))
            for turbines in shard_ranges(o.scenario.plant.n_turbines, o.shards):
                args = ["supervise", "--turbines", turbines]
                self.children.append(self._child(f"shard-{turbines}", args, supervisor_env, True))
        else:
            self.children.append(self._child("supervisor", ["supervise"], supervisor_env, True))
        plant_args = ["plant", scenario_file, "--mode", o.mode, "--speed", str(o.speed), "--seed", str(o.seed)]
        self.children.append(self._child("plant", plant_args, rt_env | self._role_env("plant"), False))
        self.info = {
            "run_id": self.run_id,
            "run_dir": str(self.run_dir),
            "zenoh": endpoint,
            "embedded_router": router is not None,
            "access_control": self.secrets is not None,
            "credentials": str(self.secrets) if self.secrets else None,
            "rerun_url": rec.url,
            "web_viewer": rec.web_url,
            "api": api_url if o.api else None,
            "docs": f"{api_url}/docs" if o.api else None,
            "events": str(self.run_dir / EVENTS),
            "recording": str(self.run_dir / RECORDING),
            "started": time.time(),
            "up_pid": os.getpid(),
            "watchdog_pid": None if self.watchdog is None else self.watchdog.proc.pid,
        }
        write_json(self.run_dir / "up.json", self.info | {"pids": self.pids})
        previous = {
            sig: signal.signal(sig, lambda *_: self.interrupted.set()) for sig in (signal.SIGINT, signal.SIGTERM)
        }
        session = open_session(self._watch_settings(endpoint))
        sub = session.declare_subscriber(KeyTree(o.farm).events_all, self._on_event)
        status_sub = session.declare_subscriber(KeyTree(o.farm).plant_status, self._on_plant_status)
        try:
            for child in self.children:
                child.start()
                self._started(child.name, child.proc.pid)
                if child.name == "api" and not _wait_http(f"{api_url}/health", 30.0, child.proc.poll):
                    console.print(f"[red]the API did not come up; see {child.log}[/red]")
                    child.failed = True
                    break
            else:
                self._banner()
                if not o.quiet:
                    self.status.start()
                self._watch()
        finally:
            self.status.stop()
            status_sub.undeclare()
            sub.undeclare()
            session.close()
            self._shutdown()
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        return self._report()

    def _watch_settings(self, endpoint: str) -> Any:
        """``up``'s own session (the event feed) is a viewer."""
        if self.secrets is None:
            return ZenohSettings(connect=endpoint, farm=self.o.farm)
        viewer = password_file(self.secrets, "viewer")
        return ZenohSettings(connect=endpoint, farm=self.o.farm, zenoh_user="viewer", zenoh_password_file=viewer)

    # -- running --------------------------------------------------------------------------------------------------
    def _banner(self) -> None:
        i, o = self.info, self.o
        if o.quiet:
            return
        console.print(
            f"[bold]windwarden up[/bold]: {self.scenario.name} ({self.scenario.plant.kind}), {o.mode} "
            f"×{o.speed:g}, {self.scenario.duration_s:g} s, seed {o.seed}, run {self.run_id}"
        )
        console.print(f"  zenoh      {i['zenoh']}" + (" (embedded router)" if i["embedded_router"] else ""))
        if o.api:
            console.print(f"  API        {i['api']}   docs {i['docs']}")
            console.print(f"  API token  {self.token}")
            example = json.dumps(kind_for(self.scenario.plant.kind).example_fault)
            console.print(
                f"  inject     curl -X POST {i['api']}/faults -H 'Authorization: Bearer {self.token}' "
                f"-H 'content-type: application/json' -d '{example}'"
            )
        if i["web_viewer"]:
            console.print(f"  watch live {i['web_viewer']}")
        else:
            console.print(
                f"  watch live rerun --connect {i['rerun_url']}    (or later: windwarden open {self.run_dir})"
            )
        console.print(f"  recording  {i['recording']}")
        console.print(f"  events     {i['events']}      logs {self.logs}/")

    def _on_plant_status(self, sample: Any) -> None:
        try:
            self.status.on_status(decode_json("plant.status", sample.payload.to_bytes()))
        except WireError:
            return

    def _on_event(self, sample: Any) -> None:
        if self.o.quiet:
            return
        try:
            event = Event.from_json(decode_json("events", sample.payload.to_bytes()))
        except (WireError, KeyError, ValueError):
            return
        self.status.on_event(event)
        if event.type in (
            EventType.FAULT_INJECTED,
            EventType.FAULT_CLEARED,
            EventType.DETECTION,
            EventType.RECOVERY,
            EventType.OBSERVER_SWITCH,
            EventType.LIVELINESS,
            EventType.STREAM,
        ):
            detail = " ".join(f"{k}={v}" for k, v in event.detail.items() if k not in ("noticed_by",))
            color = {"detection": "yellow", "fault_injected": "red", "liveliness": "cyan"}.get(event.type.value, "")
            text = f"t={event.t:8.2f} s  {event.type.value:16s} T{event.turbine} {event.target or ''} {detail}"
            console.print(f"[{color}]{text}[/{color}]" if color else text)

    def _watch(self) -> None:
        plant = next(c for c in self.children if c.name == "plant")
        while not self.interrupted.is_set():
            code = plant.proc.poll()
            if code is not None:
                plant.failed = code != 0
                return
            for child in self.children:
                if child is plant or child.proc.poll() is None:
                    continue
                child.failed = True
                console.print(f"[red]{child.name} exited with {child.proc.returncode}; see {child.log}[/red]")
                if not (self.o.restart and child.restartable and child.restarts < MAX_RESTARTS):
                    return
                child.restarts += 1
                console.print(f"restarting {child.name} ({child.restarts}/{MAX_RESTARTS})")
                child.start()
                self._started(child.name, child.proc.pid)
            self.status.tick()
            self.interrupted.wait(0.2)

    # -- shutdown -------------------------------------------------------------------------------------------------
    def _shutdown(self) -> None:
        for name in ("plant", "supervisor", "api"):
            for child in self.children:
                if _group(child.name) == name and child.proc is not None:
                    child.stop()
        time.sleep(0.3)  # the recorder receives the last rows in flight
        for proc in reversed(self.rerun):
            stop_rerun(proc, STOP_TIMEOUT_S)
        self._stop_router()  # last: its audit counts are final once it has stopped

    def _report(self) -> int:
        card = finalize_scorecard(self.run_dir)
        recording = self.run_dir / RECORDING
        verified = finalize_recording(self.run_dir) or (recording.exists() and verify_recording(recording, False))
        failed = [c.name for c in self.children if c.failed]
        completed = bool(card and card["live"]["completed"])
        refused = read_audit(self.run_dir / ROUTER_AUDIT) if self.router is not None else None
        if not self.o.quiet:
            self._print_report(card, verified, failed, refused)
        write_json(
            self.run_dir / "up.json",
            self.info
            | {
                "pids": self.pids,
                "ended": time.time(),
                "completed": completed,
                "partial": bool(card and card["live"]["partial"]),
                "failed": failed,
                "recording_verified": verified,
                "restarts": {c.name: c.restarts for c in self.children},
                "router_refused": refused,
            },
        )
        if self.interrupted.is_set():
            return 130
        return 0 if completed and not failed else 1

    def _print_report(
        self, card: dict[str, Any] | None, verified: bool, failed: list[str], refused: dict[str, Any] | None
    ) -> None:
        if card is not None:
            from windwarden.evaluation.report import render

            console.print(render({k: v for k, v in card.items() if k != "live"}))
            live = card["live"]
            lat = live["latency"]
            nan = float("nan")
            console.print(
                f"live: {live['ticks'] if live['ticks'] is not None else '?'} ticks, overruns "
                f"{live['overruns'] if live['overruns'] is not None else '?'} ({live['overrun_pct'] or nan:.2f} %), "
                f"latency p50 {lat.get('p50_ms') or nan:.2f} ms p99 {lat.get('p99_ms') or nan:.2f} ms, "
                f"real-time factor {live['real_time_factor'] or nan:.2f}"
            )
            if live.get("refs_refused"):
                console.print(f"[yellow]refs refused by the plant: {live['refs_refused']}[/yellow]")
            if live["partial"]:
                console.print(f"[red]{live['note']}[/red]")
        files = [name for name in (SCORECARD, EVENTS) if (self.run_dir / name).exists()]
        if (self.run_dir / RECORDING).exists():
            files.append(f"{RECORDING} ({'verified' if verified else 'NOT verified'})")
        console.print(
            f"run folder {self.run_dir}: {', '.join(files) if files else 'no run files (the plant never ran)'}"
        )
        if refused is not None:
            console.print(
                f"router: {refused['denied_total']} messages denied, {refused['logins_refused_total']} logins "
                f"refused ({self.run_dir / ROUTER_AUDIT})"
            )
        if failed:
            console.print(f"[red]failed: {', '.join(failed)} (logs in {self.logs})[/red]")


def _group(child: str) -> str:
    """The shutdown group of a child: a sharded supervisor's coordinator and shards stop with the supervisors."""
    return "supervisor" if child == "coordinator" or child.startswith("shard-") else child
