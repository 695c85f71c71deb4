"""Who may do what on the Zenoh network: the roles, their grants, credentials, and the router's configuration.

The router denies by default and allows each role only what it needs (``role_grants``); a client proves its role
with a user name and password (Zenoh ``usrpwd`` authentication, the user name is the role) or with a TLS client
certificate whose common name is the role. The grants follow from what each process does:

* **plant**: puts sensors, truth, the met mast, its status and its events; serves ``plant/run``, ``plant/faults``
  and ``plant/status``; receives refs and the supervisor's status;
* **supervisor**: puts refs, its status and its events; receives sensors, the met mast and the plant's events; asks
  ``plant/run`` and ``plant/status`` (the plant's tick, to confirm a frame after a long gap); serves
  ``supervisor/status``; the shards and the coordinator of a sharded farm supervisor log in with this role and put
  and receive the turbines' summaries, the dispatch rows and the shards' status besides;
* **api**: receives both event streams; asks ``plant/status``, ``plant/run``, ``plant/faults`` and
  ``supervisor/status``;
* **viewer** (dashboards, recorders, ``windwarden up``'s event feed, health probes): receives everything of the
  farm, puts and asks nothing;
* every role declares the liveliness token of its own process (viewers none) and watches all of them.

What each operation needs of the router was found by experiment with eclipse-zenoh 1.10.2 (remove one permission
at a time and see the operation fail), see ``docs/live.md``: a publication needs ``put`` ingress from the
publisher and ``declare_subscriber`` egress to it (a declared publisher sends nothing until the router has told
it of a subscriber), and for each subscriber ``declare_subscriber`` ingress and ``put`` egress to it; a query
needs ``query`` ingress from the asker (and ``declare_queryable`` egress to a declared querier), ``query`` egress
to the queryable, ``reply`` ingress from it and ``reply`` egress back (``reply_err`` is a ``reply``); a liveliness
token needs ``liveliness_token`` ingress from its owner and egress to each watcher, whose
``declare_liveliness_subscriber`` or ``liveliness_query`` must come in.
A subscription on a wildcard (``*/events``) is allowed only by a rule whose key expression includes it; what is
delivered through it is still filtered by the ``put`` egress rules.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wwcore.keys import KeyTree, Process

ROLES: tuple[str, ...] = ("plant", "supervisor", "api", "viewer")
USERS_FILE = "zenoh-users.txt"  # the router's dictionary: one ``user:password`` line per role
PASSWORD_SUFFIX = ".password"


@dataclass(frozen=True)
class Grant:
    """One allow rule: Zenoh message kinds, on one flow as seen by the router, on key expressions."""

    messages: tuple[str, ...]
    flow: str  # "ingress": from the role into the router; "egress": from the router to the role
    keys: tuple[str, ...]


def _publish(*keys: str) -> list[Grant]:
    return [Grant(("put",), "ingress", keys)]


def _subscribe(*keys: str, delivered: Iterable[str] | None = None) -> list[Grant]:
    """Subscribe on ``keys``; receive puts on ``delivered`` (default: the same keys)."""
    return [
        Grant(("declare_subscriber",), "ingress", keys),
        Grant(("put",), "egress", tuple(delivered) if delivered is not None else keys),
    ]


def _serve(*keys: str) -> list[Grant]:
    return [
        Grant(("declare_queryable",), "ingress", keys),
        Grant(("query",), "egress", keys),
        Grant(("reply",), "ingress", keys),
    ]


def _ask(*keys: str) -> list[Grant]:
    return [Grant(("query",), "ingress", keys), Grant(("reply",), "egress", keys)]


def _discover(k: KeyTree) -> list[Grant]:
    """Learn which subscribers and queryables exist: a Zenoh 1.x client drops the puts of a declared publisher (and
    the gets of a declared querier) for which the router has declared no subscriber (queryable) to it. The
    declarations carry the subscriber's key expression (a viewer's ``windwarden/<farm>/**``), hence the wide key;
    they reveal who listens, never any data."""
    return [Grant(("declare_subscriber", "declare_queryable"), "egress", (f"{k.base}/**",))]


def _liveliness(k: KeyTree, own: str | None) -> list[Grant]:
    watch = [
        Grant(("declare_liveliness_subscriber", "liveliness_query"), "ingress", (k.alive_all,)),
        Grant(("liveliness_token",), "egress", (k.alive_all,)),
    ]
    return ([Grant(("liveliness_token",), "ingress", (k.alive(own),))] if own else []) + watch


def role_grants(keys: KeyTree | None = None) -> dict[str, list[Grant]]:
    """Every role's allow rules on the key tree ``keys`` (default: every farm, ``windwarden/*/…``)."""
    k = keys or KeyTree.every_farm()
    t = "*"
    sharded = (k.summary(t), k.dispatch(t), k.shard_status(t))  # a sharded farm supervisor's own keys
    return {
        "plant": [
            *_publish(k.sensors, k.truth, k.metmast, k.plant_status, k.plant_events),
            *_serve(k.run, k.faults, k.plant_status),
            *_subscribe(k.refs(t), k.supervisor_status),
            *_liveliness(k, Process.PLANT),
            *_discover(k),
        ],
        "supervisor": [  # and the shards and the coordinator of a sharded farm supervisor, their keys besides
            *_publish(k.refs(t), k.supervisor_status, k.supervisor_events, *sharded),
            *_subscribe(k.sensors, k.metmast, k.plant_events, *sharded),
            *_ask(k.run, k.plant_status),  # plant/status: a gap's tick confirmed (guard.FrameSequencer)
            *_serve(k.supervisor_status),
            *_liveliness(k, Process.SUPERVISOR),
            *_discover(k),
        ],
        "api": [
            *_subscribe(k.events_all, delivered=(k.plant_events, k.supervisor_events)),
            *_ask(k.plant_status, k.run, k.faults, k.supervisor_status),
            *_liveliness(k, Process.API),
            *_discover(k),
        ],
        "viewer": [
            *_subscribe(f"{k.base}/**"),
            *_liveliness(k, None),
            *_discover(k),
        ],
    }


def access_control(keys: KeyTree | None = None, roles: Iterable[str] = ROLES) -> dict[str, Any]:
    """The router's ``access_control`` section: default deny, each role's grants, and two subjects per role (the
    user name, and the common name of a TLS client certificate; either identifies the role)."""
    grants = role_grants(keys)
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for role in roles:
        ids = []
        for i, grant in enumerate(grants[role]):
            rule_id = f"{role}-{i}-{grant.flow}-{'-'.join(grant.messages)}"
            ids.append(rule_id)
            rules.append(
                {
                    "id": rule_id,
                    "permission": "allow",
                    "flows": [grant.flow],
                    "messages": list(grant.messages),
                    "key_exprs": list(grant.keys),
                }
            )
        subjects += [{"id": f"{role}-user", "usernames": [role]}, {"id": f"{role}-cert", "cert_common_names": [role]}]
        policies.append({"rules": ids, "subjects": [f"{role}-user", f"{role}-cert"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}


# -- credentials -----------------------------------------------------------------------------------------------------
def new_passwords(roles: Iterable[str] = ROLES) -> dict[str, str]:
    """A fresh random password per role (URL-safe, so never a ``:`` that would break the users file)."""
    return {role: secrets.token_urlsafe(24) for role in roles}


def _write_private(path: Path, text: str, mode: int) -> None:
    """Create ``path`` with ``mode`` from the start (never readable by others, even for a moment)."""
    path.unlink(missing_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode)
    with os.fdopen(fd, "w") as out:
        out.write(text)
    os.chmod(path, mode)  # os.open's mode is masked by the umask


def write_credentials(folder: Path, passwords: Mapping[str, str], file_mode: int = 0o600) -> Path:
    """``folder/<role>.password`` for each client and ``folder/zenoh-users.txt`` for the router; the folder is
    created with mode 0700 and the files with ``file_mode`` (0600: only this user reads them). Returns the users
    file."""
    folder.mkdir(parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    for role, password in passwords.items():
        _write_private(folder / f"{role}{PASSWORD_SUFFIX}", password + "\n", file_mode)
    users = folder / USERS_FILE
    _write_private(users, "".join(f"{role}:{pw}\n" for role, pw in passwords.items()), file_mode)
    return users


def read_password(path: Path) -> str:
    """The password in a secret file (first line, surrounding white space removed); ``ValueError`` if empty."""
    text = path.read_text().strip()
    if not text or "\n" in text:
        raise ValueError(f"{path} must hold exactly one non-empty line (the password)")
    return text


def password_file(folder: Path, role: str) -> Path:
    return folder / f"{role}{PASSWORD_SUFFIX}"


def check_users_file(path: Path) -> list[str]:
    """The user names in a router dictionary file; ``ValueError`` naming the first bad line."""
    users = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        user, sep, password = line.partition(":")
        if not sep or not user or not password:
            raise ValueError(f"{path}:{n}: expected user:password")
        users.append(user)
    if not users:
        raise ValueError(f"{path} holds no user")
    return users
