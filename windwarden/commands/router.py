"""``windwarden router`` (the Zenoh router with access control, as a service) and ``windwarden credentials``
(a password per role and the router's users file, for compose or for a router you run yourself).

Secrets never travel on a command line: the router reads its users file, each client its password file
(``WINDWARDEN_ZENOH_PASSWORD_FILE``); only paths are given as flags or variables.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import threading
from pathlib import Path
from typing import Any

from windwarden.commands.common import BadInputError
from windwarden.live.process import exit_with_parent, on_signals, setup_logging

log = logging.getLogger("windwarden.live")


def _env_path(name: str) -> Path | None:
    value = os.environ.get(name)
    return Path(value) if value else None


# -- router ----------------------------------------------------------------------------------------------------------
def _add_router(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "router",
        help="run the Zenoh router with access control (what `up` starts; compose can run it instead of zenohd)",
    )
    p.add_argument(
        "--listen",
        default=os.environ.get("WINDWARDEN_LISTEN") or None,
        help="endpoints, comma-separated (default tcp/127.0.0.1:7447; in a container tcp/0.0.0.0:7447)",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=_env_path("WINDWARDEN_ROUTER_CONFIG"),
        help="run this zenohd configuration file (JSON5) as it is, e.g. docker/zenoh/router.json5",
    )
    p.add_argument(
        "--users",
        type=Path,
        default=_env_path("WINDWARDEN_ZENOH_USERS_FILE"),
        help="users file, one user:password line per role (`windwarden credentials` writes one)",
    )
    p.add_argument("--farm", default=None, help="write the rules for this farm only (default: every farm)")
    p.add_argument("--tls-ca", type=Path, default=None, help="CA the clients' certificates must chain to (PEM)")
    p.add_argument("--tls-cert", type=Path, default=None, help="the router's certificate (PEM), for tls/ endpoints")
    p.add_argument("--tls-key", type=Path, default=None, help="the router's private key (PEM)")
    p.add_argument("--no-acl", action="store_true", help="no access control: anyone may do anything (development)")
    p.add_argument(
        "--audit",
        type=Path,
        default=_env_path("WINDWARDEN_ROUTER_AUDIT"),
        help="count denied messages and refused logins into this JSON file (reads Zenoh's trace log)",
    )
    p.add_argument("--print-config", action="store_true", help="print the configuration as a zenohd file, exit")
    p.set_defaults(func=cmd_router)


def router_access(args: argparse.Namespace) -> Any:
    """The ``RouterAccess`` the flags ask for (None with ``--no-acl``)."""
    from windwarden.live.router import RouterAccess, TlsFiles

    if args.no_acl:
        return None
    tls_parts = (args.tls_ca, args.tls_cert, args.tls_key)
    if any(tls_parts) and not all(tls_parts):
        raise BadInputError("TLS needs --tls-ca, --tls-cert and --tls-key together")
    tls = TlsFiles(*tls_parts) if all(tls_parts) else None
    if args.users is None and tls is None:
        raise BadInputError(
            "the router needs credentials: --users FILE (see `windwarden credentials`), TLS client certificates "
            "(--tls-ca/--tls-cert/--tls-key), or --no-acl for an open router"
        )
    try:
        return RouterAccess(users_file=args.users, farm=args.farm, tls=tls)
    except (OSError, ValueError) as error:
        raise BadInputError(str(error)) from None


def cmd_router(args: argparse.Namespace) -> int:
    import zenoh

    from windwarden.live.audit import RouterAudit
    from windwarden.live.router import DEFAULT_PORT, router_config, router_file_config

    setup_logging("router")
    listen = [e.strip() for e in (args.listen or f"tcp/127.0.0.1:{DEFAULT_PORT}").split(",") if e.strip()]
    access = None if args.config is not None else router_access(args)
    if args.print_config:
        if args.config is not None or access is None:
            raise BadInputError("--print-config prints the access-controlled configuration: give --users or TLS")
        sys.stdout.write(router_file_config(listen, access))
        return 0
    audit = RouterAudit(args.audit) if args.audit else None
    if audit is not None:
        audit.start()  # before the session: Zenoh's log goes to the audit from the start
    else:
        zenoh.init_log_from_env_or("warn")
    try:
        if args.config is not None:
            config = zenoh.Config.from_file(str(args.config))
            if args.listen:
                config.insert_json5("listen/endpoints", json.dumps(listen))
            what = f"configuration {args.config}"
        else:
            config = router_config(listen, access=access)
            what = "no access control" if access is None else "access control, default deny"
        session = zenoh.open(config)
    except (zenoh.ZError, OSError, ValueError) as error:
        log.error("the router cannot start: %s", error)
        return 1
    where = ",".join(listen) if args.listen or args.config is None else "the file's endpoints"
    log.info("router %s listening on %s (%s)", session.info.zid(), where, what)
    stopped = threading.Event()
    on_signals(stopped.set)
    exit_with_parent(stopped.set)
    stopped.wait()
    session.close()
    if audit is not None:
        audit.close()
        counts = audit.counts()
        log.info(
            "router stops: %d messages denied, %d logins refused",
            counts["denied_total"],
            counts["logins_refused_total"],
        )
    return 0


# -- credentials -----------------------------------------------------------------------------------------------------
def _add_credentials(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "credentials",
        help="write a new password per role and the router's users file into a folder (for compose)",
    )
    p.add_argument("folder", type=Path, help="where: <role>.password and zenoh-users.txt (e.g. docker/secrets)")
    p.add_argument("--force", action="store_true", help="replace existing credentials")
    p.add_argument(
        "--container",
        action="store_true",
        help="files readable by the containers' non-root user (mode 0644 in a 0700 folder; compose mounts files "
        "with their host mode)",
    )
    p.set_defaults(func=cmd_credentials)


def cmd_credentials(args: argparse.Namespace) -> int:
    from windwarden.live.access import ROLES, USERS_FILE, new_passwords, write_credentials

    if (args.folder / USERS_FILE).exists() and not args.force:
        raise BadInputError(f"{args.folder} already holds credentials (--force replaces them)")
    users = write_credentials(args.folder, new_passwords(), 0o644 if args.container else 0o600)
    sys.stdout.write(
        f"wrote {', '.join(f'{r}.password' for r in ROLES)} and {users.name} in {args.folder} "
        f"(folder mode 0700, files {'0644' if args.container else '0600'})\n"
    )
    return 0


ROUTER_SUBCOMMANDS = [_add_router, _add_credentials]
