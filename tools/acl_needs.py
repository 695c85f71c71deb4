"""Which access-control permissions each Zenoh operation needs, found by experiment (docs/live.md, "Access control").

For each operation between two clients ``a`` (who does it) and ``b`` (the other side), on a Python router with
user/password authentication and access control: allow every (user, message, flow) on ``t/**`` and check the
operation works; allow nothing and check it fails; then remove one permission at a time and keep those whose
removal breaks it; finally check the operation works with only those. Each trial opens a fresh router on a free
loopback port (~0.5–1.5 s), so one operation takes about 40 trials.

    .venv/bin/python tools/acl_needs.py                       # every operation (a few minutes)
    .venv/bin/python tools/acl_needs.py publisher_first querier
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import zenoh

from windwarden.live.router import free_port

MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
)
FLOWS = ("ingress", "egress")
USERS = {"a": "password-a", "b": "password-b"}
Permission = tuple[str, str, str]  # (user, message, flow)


def _router(endpoint: str, allowed: set[Permission], users_file: Path) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"')
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(users_file)))
    rules = [
        {"id": f"r{i}", "permission": "allow", "flows": [f], "messages": [m], "key_exprs": ["t/**"]}
        for i, (_, m, f) in enumerate(sorted(allowed))
    ]
    policies = [{"rules": [f"r{i}"], "subjects": [f"s_{u}"]} for i, (u, _, _) in enumerate(sorted(allowed))]
    subjects = [{"id": f"s_{u}", "usernames": [u]} for u in USERS]
    acl = {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}
    conf.insert_json5("access_control", json.dumps(acl))
    return zenoh.open(conf)


def _client(endpoint: str, user: str) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
    conf.insert_json5("transport/auth/usrpwd/password", json.dumps(USERS[user]))
    return zenoh.open(conf)


def _deliver(put: Callable[[], None], got: threading.Event) -> bool:
    for _ in range(5):
        put()
        if got.wait(0.1):
            return True
    return False


def subscriber_first(a: zenoh.Session, b: zenoh.Session) -> bool:
    """b subscribes, a declares a publisher, waits for the router's answer, then puts."""
    got = threading.Event()
    b.declare_subscriber("t/x", lambda s: got.set())
    time.sleep(0.3)
    pub = a.declare_publisher("t/x")
    time.sleep(0.5)
    return _deliver(lambda: pub.put(b"1"), got)


def publisher_first(a: zenoh.Session, b: zenoh.Session) -> bool:
    """a declares a publisher, then b subscribes, then a puts."""
    got = threading.Event()
    pub = a.declare_publisher("t/x")
    time.sleep(0.3)
    b.declare_subscriber("t/x", lambda s: got.set())
    time.sleep(0.3)
    return _deliver(lambda: pub.put(b"1"), got)


def session_put(a: zenoh.Session, b: zenoh.Session) -> bool:
    """a puts without declaring a publisher."""
    got = threading.Event()
    b.declare_subscriber("t/x", lambda s: got.set())
    time.sleep(0.3)
    return _deliver(lambda: a.put("t/x", b"1"), got)


def query(a: zenoh.Session, b: zenoh.Session) -> bool:
    """a asks (session.get), b's queryable answers."""
    b.declare_queryable("t/q", lambda q: q.reply("t/q", b"ok"))
    time.sleep(0.3)
    return any(r.ok is not None for r in a.get("t/q", timeout=1.0))


def querier(a: zenoh.Session, b: zenoh.Session) -> bool:
    """a asks through a declared querier, b's queryable answers."""
    b.declare_queryable("t/q", lambda q: q.reply("t/q", b"ok"))
    time.sleep(0.3)
    asker = a.declare_querier("t/q", timeout=1.0)
    time.sleep(0.3)
    return any(r.ok is not None for r in asker.get())


def liveliness_subscriber(a: zenoh.Session, b: zenoh.Session) -> bool:
    """b watches, a declares a token."""
    got = threading.Event()
    b.liveliness().declare_subscriber("t/alive/*", lambda s: got.set())
    time.sleep(0.3)
    token = a.liveliness().declare_token("t/alive/a")  # a token lives as long as its object
    alive = got.wait(1.0)
    token.undeclare()
    return alive


def liveliness_history(a: zenoh.Session, b: zenoh.Session) -> bool:
    """a declares a token, then b watches with history."""
    token = a.liveliness().declare_token("t/alive/a")
    time.sleep(0.3)
    got = threading.Event()
    b.liveliness().declare_subscriber("t/alive/*", lambda s: got.set(), history=True)
    alive = got.wait(1.0)
    token.undeclare()
    return alive


def liveliness_get(a: zenoh.Session, b: zenoh.Session) -> bool:
    """a declares a token, b asks who is alive."""
    token = a.liveliness().declare_token("t/alive/a")
    time.sleep(0.3)
    alive = any(r.ok is not None for r in b.liveliness().get("t/alive/*", timeout=1.0))
    token.undeclare()
    return alive


OPERATIONS = {
    f.__name__: f
    for f in (
        subscriber_first,
        publisher_first,
        session_put,
        query,
        querier,
        liveliness_subscriber,
        liveliness_history,
        liveliness_get,
    )
}


def trial(operation: str, allowed: set[Permission], users_file: Path) -> bool:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with _router(endpoint, allowed, users_file):
        a, b = _client(endpoint, "a"), _client(endpoint, "b")
        try:
            return OPERATIONS[operation](a, b)
        finally:
            a.close()
            b.close()


def needs(operation: str, users_file: Path) -> dict[str, object]:
    everything = {(u, m, f) for u in USERS for m in MESSAGES for f in FLOWS}
    works, blocked = trial(operation, everything, users_file), not trial(operation, set(), users_file)
    needed = sorted(p for p in everything if works and not trial(operation, everything - {p}, users_file))
    return {
        "works with everything allowed": works,
        "fails with nothing allowed": blocked,
        "needed": [f"{u}: {m} {f}" for u, m, f in needed],
        "works with only those": trial(operation, set(needed), users_file) if works else None,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("operations", nargs="*", choices=[*OPERATIONS, []], help="default: all")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        users_file = Path(folder) / "users.txt"
        users_file.write_text("".join(f"{u}:{p}\n" for u, p in USERS.items()))
        for operation in args.operations or OPERATIONS:
            print(operation, json.dumps(needs(operation, users_file)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
