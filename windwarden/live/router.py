"""The Zenoh router of the live system: a Python session in router mode, so one machine needs no ``zenohd``.

``windwarden router`` runs it as a service (what ``windwarden up`` starts as its first child, and what the compose
file can run from the project's image instead of ``eclipse/zenoh``); ``open_router`` opens one in the calling
process (tests). The router listens on explicit TCP (or TLS) endpoints with multicast scouting off; clients
(plant, supervisor, API, viewers) connect to it. With ``RouterAccess`` it enforces Zenoh access control: default
deny, each role's grants (``windwarden.live.access``), clients authenticated by user name and password and/or by
TLS client certificate.

``router_file_config`` writes the same configuration as a zenohd configuration file (``docker/zenoh/router.json5``),
so ``zenohd -c`` and ``windwarden router --config`` enforce the same rules.
"""

from __future__ import annotations

import json
import random
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from windwarden.live.access import access_control, check_users_file
from windwarden.live.config import ZenohSettings
from windwarden.live.transport import zenoh_config
from wwcore.keys import KeyTree

DEFAULT_PORT = 7447


EPHEMERAL_RANGE = Path("/proc/sys/net/ipv4/ip_local_port_range")
LOWEST_LISTEN_PORT = 10_000  # above the ports services are usually configured on


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that was free a moment ago (for tests and ``up --listen auto``).

    Drawn at random below the kernel's ephemeral range where it is known (Linux): a port the kernel hands out
    (``bind`` to port 0) is one it also hands to outgoing connections, and another process's connection could take
    it before the caller listens on it (seen: a service of the compose test failed with "address already in use" on
    such a port while the other services connected to the router). Elsewhere, the kernel's choice."""
    try:
        low = int(EPHEMERAL_RANGE.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        low = 0
    rng = random.SystemRandom()
    for _ in range(50 if low > LOWEST_LISTEN_PORT + 1000 else 0):
        port = rng.randrange(LOWEST_LISTEN_PORT, low)
        with socket.socket() as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return port
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


@dataclass(frozen=True)
class TlsFiles:
    """The router's TLS identity and the CA its clients' certificates must chain to (mutual TLS)."""

    ca: Path
    cert: Path
    key: Path


@dataclass(frozen=True)
class RouterAccess:
    """Access control for a router: the users file (``user:password`` lines; None: no password login), the farm
    the rules are written for (None: every farm) and TLS files (None: no TLS endpoint)."""

    users_file: Path | None = None
    farm: str | None = None
    tls: TlsFiles | None = None

    def __post_init__(self) -> None:
        if self.users_file is None and self.tls is None:
            raise ValueError("access control needs a users file or TLS client certificates to tell the roles apart")

    def check(self) -> None:
        """``ValueError``/``OSError`` if the users file cannot be read or has a bad line."""
        if self.users_file is not None:
            check_users_file(self.users_file)

    def sections(self) -> dict[str, Any]:
        """Config path → value of everything access control adds to a router's configuration."""
        keys = KeyTree(self.farm) if self.farm else None
        out: dict[str, Any] = {"access_control": access_control(keys)}
        if self.users_file is not None:
            out["transport/auth/usrpwd/dictionary_file"] = str(self.users_file)
        if self.tls is not None:
            out["transport/link/tls"] = {
                "root_ca_certificate": str(self.tls.ca),
                "listen_certificate": str(self.tls.cert),
                "listen_private_key": str(self.tls.key),
                "enable_mtls": True,
            }
        return out


def router_config(listen: list[str], settings: ZenohSettings | None = None, access: RouterAccess | None = None):
    """The zenoh.Config of a router on ``listen`` (with access control if ``access``)."""
    base = settings or ZenohSettings()
    conf = base.model_copy(
        update={"listen": ",".join(listen), "connect": "", "zenoh_mode": "router", "zenoh_user": None}
    )
    if access is not None:
        access.check()
    config = zenoh_config(conf)
    for path, value in (access.sections() if access else {}).items():
        config.insert_json5(path, json.dumps(value))
    return config


def open_router(
    listen: list[str], settings: ZenohSettings | None = None, access: RouterAccess | None = None
) -> zenoh.Session:
    """A router session listening on ``listen``; close it (or use it as a context manager) to stop routing."""
    return zenoh.open(router_config(listen, settings, access))


def router_file_config(listen: list[str], access: RouterAccess, settings: ZenohSettings | None = None) -> str:
    """The router's configuration as a zenohd JSON5 file (same lease, scouting and access control as
    ``router_config``)."""
    base = settings or ZenohSettings()
    data: dict[str, Any] = {
        "mode": "router",
        "listen": {"endpoints": listen},
        "scouting": {"multicast": {"enabled": base.multicast}},
        "transport": {"link": {"tx": {"lease": base.lease_ms, "keep_alive": 4}}},
    }
    for path, value in access.sections().items():
        node = data
        *parents, leaf = path.split("/")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    header = (
        "// windwarden's Zenoh router: default deny, one role per user (see docs/live.md, 'Access control').\n"
        "// Generated by `windwarden router --print-config`; tests/live/test_access.py checks it is current.\n"
    )
    return header + _json5_lines(data) + "\n"


def _json5_lines(value: Any, indent: str = "") -> str:
    """JSON with one line per rule, subject and policy (lists of scalars and small objects stay on one line)."""
    inner = indent + "  "
    if isinstance(value, dict) and any(isinstance(v, dict | list) for v in value.values()):
        items = [f"{inner}{json.dumps(k)}: {_json5_lines(v, inner)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{indent}}}"
    if isinstance(value, list) and any(isinstance(v, dict) for v in value):
        return "[\n" + ",\n".join(f"{inner}{json.dumps(v)}" for v in value) + f"\n{indent}]"
    return json.dumps(value)


def wait_listening(endpoint: str, timeout: float, alive: Any = None) -> bool:
    """Until a TCP connection to ``endpoint`` (tcp/ or tls/ host:port) succeeds, or ``timeout``, or ``alive()``
    says the router process has exited."""
    host, _, port = endpoint.split("/", 1)[1].rpartition(":")
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if alive is not None and alive() is not None:
            return False
        try:
            with socket.create_connection((host.strip("[]"), int(port)), timeout=0.5):
                return True
        except OSError:
            time.sleep(0.05)
    return False


def start_router_process(
    endpoint: str, access: RouterAccess | None, log: Path, audit: Path | None = None, env: dict[str, str] | None = None
) -> subprocess.Popen:
    """``windwarden router`` as a child process in its own session (its output in ``log``); ``env`` is its whole
    environment (the users file is passed by path, never its content)."""
    argv = [sys.executable, "-m", "windwarden.cli", "router", "--listen", endpoint]
    if access is None:
        argv.append("--no-acl")
    else:
        if access.users_file is not None:
            argv += ["--users", str(access.users_file)]
        if access.farm:
            argv += ["--farm", access.farm]
        if access.tls is not None:
            argv += [
                "--tls-ca",
                str(access.tls.ca),
                "--tls-cert",
                str(access.tls.cert),
                "--tls-key",
                str(access.tls.key),
            ]
    if audit is not None:
        argv += ["--audit", str(audit)]
    with log.open("ab") as out:
        return subprocess.Popen(
            argv, env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True
        )


def read_audit(path: Path) -> dict[str, Any] | None:
    """The counts a router with ``--audit`` wrote, or None."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None
