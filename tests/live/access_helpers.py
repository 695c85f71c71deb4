"""A router with access control in its own process (``windwarden router``, as ``up`` runs it) and sessions that
log in with a role's credentials, for the access-control tests."""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from windwarden.live.access import USERS_FILE, new_passwords, password_file, write_credentials
from windwarden.live.config import ZenohSettings
from windwarden.live.recorder import stop
from windwarden.live.router import RouterAccess, TlsFiles, free_port, start_router_process, wait_listening
from windwarden.live.transport import open_session


@dataclass
class AclRouter:
    endpoint: str
    secrets: Path
    audit: Path
    log: Path
    proc: Any

    def session(self, role: str | None, **settings: Any) -> zenoh.Session:
        """A client session logged in as ``role`` (None: no credentials)."""
        creds = {} if role is None else {"zenoh_user": role, "zenoh_password_file": password_file(self.secrets, role)}
        return open_session(ZenohSettings(connect=self.endpoint, **creds, **settings))

    def counts(self) -> dict[str, Any]:
        """The audit's counts (final once the router has stopped)."""
        return json.loads(self.audit.read_text())

    def stop(self) -> dict[str, Any]:
        stop(self.proc, 10.0)
        return self.counts()


def clean_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if not k.startswith(("WINDWARDEN_", "RUST_LOG"))}


@contextlib.contextmanager
def acl_router(folder: Path, tls: TlsFiles | None = None, endpoint: str | None = None) -> Iterator[AclRouter]:
    """``windwarden router`` with new credentials in ``folder/secrets``, access control for farm ``default`` and the
    audit on; with ``tls``, client certificates identify the roles (no password login)."""
    folder.mkdir(parents=True, exist_ok=True)
    secrets = folder / "secrets"
    users = write_credentials(secrets, new_passwords())
    endpoint = endpoint or f"tcp/127.0.0.1:{free_port()}"
    access = RouterAccess(None if tls else users, farm="default", tls=tls)
    log, audit = folder / "router.log", folder / "router.json"
    proc = start_router_process(endpoint, access, log, audit, clean_env())
    router = AclRouter(endpoint, secrets, audit, log, proc)
    try:
        assert wait_listening(endpoint, 30.0, proc.poll), f"the router did not start: {log.read_text()}"
        yield router
    finally:
        stop(proc, 10.0)


__all__ = ["USERS_FILE", "AclRouter", "acl_router", "clean_env"]
