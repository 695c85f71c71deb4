"""Access control on the router, role by role: what each role may and may not do, checked on a real router process
(``windwarden router``) with one session per role, against a table written from the issue's requirements (not from
the grants in ``windwarden.live.access``): only the plant may put sensors, truth, its status and its events; only the
supervisor refs, its status and its events; only the API may query the plant's fault and status queryables (the
supervisor also asks ``plant/run``); viewers may subscribe to everything and do nothing else; a session without
credentials, or with a wrong password, cannot connect. Every refused put is counted by the router's audit.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh

from tests.live.access_helpers import acl_router, clean_env
from tests.live.helpers import wait_for
from windwarden.live.access import ROLES, new_passwords, write_credentials
from windwarden.live.audit import RouterAudit
from windwarden.live.config import ZenohSettings
from windwarden.live.router import RouterAccess, TlsFiles, router_file_config
from windwarden.live.transport import open_session
from wwcore.keys import KeyTree

ROOT = Path(__file__).resolve().parents[2]
K = KeyTree("default")
SETTLE_S = 1.0  # after which a message that has not arrived will not arrive (loopback, idle router)

PUTS = {  # key → the only role that may put on it
    K.sensors: "plant",
    K.truth: "plant",
    K.plant_status: "plant",
    K.plant_events: "plant",
    K.refs("supervisor"): "supervisor",
    K.supervisor_status: "supervisor",
    K.supervisor_events: "supervisor",
    K.summary("1-40"): "supervisor",  # a sharded supervisor: shard → coordinator
    K.dispatch("1-40"): "supervisor",  # coordinator → shard
    K.shard_status("1-4"): "supervisor",
    f"{K.base}/elsewhere": None,
}
QUERIES = {  # queryable key → roles that may ask it
    K.faults: {"api"},
    K.plant_status: {"api", "supervisor"},  # the supervisor confirms a tick after a gap (guard.FrameSequencer)
    K.run: {"api", "supervisor"},
    K.supervisor_status: {"api"},
}
SUBSCRIPTIONS = {  # key → roles that receive what is put on it
    K.sensors: {"supervisor", "viewer"},
    K.refs("supervisor"): {"plant", "viewer"},
    K.plant_events: {"supervisor", "api", "viewer"},
    K.supervisor_events: {"api", "viewer"},
    K.truth: {"viewer"},
    K.summary("1-40"): {"supervisor", "viewer"},
    K.dispatch("1-40"): {"supervisor", "viewer"},
    K.shard_status("1-4"): {"supervisor", "viewer"},
}
TOKENS = {K.alive("plant"): "plant", K.alive("supervisor"): "supervisor"}


def test_each_role_may_do_only_its_own_part(tmp_path):
    with acl_router(tmp_path) as router:
        sessions = {role: router.session(role) for role in ROLES}
        witness = router.session("viewer")  # sees every put the router lets through
        api = router.session("api")  # asks the queryables others declare
        try:
            # -- puts: every role puts a marked message on every key; the witness sees which got through
            seen: list[tuple[str, bytes]] = []
            lock = threading.Lock()

            def record(sample):
                with lock:
                    seen.append((str(sample.key_expr), sample.payload.to_bytes()))

            witness_sub = witness.declare_subscriber(f"{K.base}/**", record)
            time.sleep(0.3)
            for key in PUTS:
                for role, session in sessions.items():
                    session.put(key, f"{role}|{key}".encode())
            expected = {(key, f"{owner}|{key}".encode()) for key, owner in PUTS.items() if owner}
            assert wait_for(lambda: expected <= set(seen), 5.0), f"missing: {expected - set(seen)}"
            time.sleep(SETTLE_S)
            assert set(seen) == expected, f"let through: {set(seen) - expected}"
            witness_sub.undeclare()

            # -- subscriptions: every role subscribes to every key; the rightful publisher puts
            got: dict[tuple[str, str], int] = {}
            subs = []
            for key in SUBSCRIPTIONS:
                for role, session in sessions.items():

                    def count(sample, role=role, key=key):
                        with lock:
                            got[(role, key)] = got.get((role, key), 0) + 1

                    subs.append(session.declare_subscriber(key, count))
            time.sleep(0.5)
            for key in SUBSCRIPTIONS:
                sessions[PUTS[key]].put(key, b"x")
            wanted = {(role, key) for key, roles in SUBSCRIPTIONS.items() for role in roles}
            # a subscriber receives its own session's puts locally, without the router: not a delivery
            wanted |= {(PUTS[key], key) for key in SUBSCRIPTIONS}
            assert wait_for(lambda: wanted <= set(got), 5.0), f"not delivered: {wanted - set(got)}"
            time.sleep(SETTLE_S)
            assert set(got) == wanted, f"delivered to: {set(got) - wanted}"
            for sub in subs:
                sub.undeclare()

            # -- queries: the plant and the supervisor serve; every role asks
            served = [
                sessions["plant"].declare_queryable(key, lambda q: q.reply(q.key_expr, b"ok"))
                for key in (K.faults, K.plant_status, K.run)
            ]
            served.append(
                sessions["supervisor"].declare_queryable(K.supervisor_status, lambda q: q.reply(q.key_expr, b"ok"))
            )
            time.sleep(0.5)
            servers = {K.faults: "plant", K.plant_status: "plant", K.run: "plant", K.supervisor_status: "supervisor"}
            for key, askers in QUERIES.items():
                for role, session in sessions.items():
                    if role == servers[key]:
                        continue  # a session answers its own queries locally, without the router
                    answered = any(r.ok is not None for r in session.get(key, timeout=1.0))
                    assert answered == (role in askers), f"{role} asking {key}: answered={answered}"
            for q in served:
                q.undeclare()

            # -- impersonation: a queryable on plant/faults (answering the API's fault commands), a liveliness
            # token on another process's key
            for role, session in sessions.items():
                fake = session.declare_queryable(K.faults, lambda q: q.reply(q.key_expr, b"fake"))
                time.sleep(0.3)
                answered = any(r.ok is not None for r in api.get(K.faults, timeout=1.0))
                fake.undeclare()
                assert answered == (role == "plant"), f"{role} serving plant/faults: answered={answered}"
            for key, owner in TOKENS.items():
                for role, session in sessions.items():
                    token = session.liveliness().declare_token(key)
                    time.sleep(0.3)
                    alive = any(r.ok is not None for r in witness.liveliness().get(key, timeout=1.0))
                    token.undeclare()
                    time.sleep(0.2)
                    assert alive == (role == owner), f"{role} token on {key}: alive={alive}"
        finally:
            for s in [*sessions.values(), witness, api]:
                s.close()
        counts = router.stop()
    denied_puts = {
        (d["role"], d["key"]): d["count"] for d in counts["denied"] if d["message"] == "put" and d["flow"] == "ingress"
    }
    for key, owner in PUTS.items():
        for role in ROLES:
            if role != owner:
                assert denied_puts.get((role, key), 0) >= 1, f"the audit did not count {role}'s put on {key}"
    assert all(role in ROLES for role, _ in denied_puts)


def test_no_credentials_or_wrong_password_cannot_connect(tmp_path):
    with acl_router(tmp_path) as router:
        with pytest.raises(zenoh.ZError):
            router.session(None, connect_timeout_s=1.0)
        (tmp_path / "wrong").write_text("not-the-password\n")
        with pytest.raises(zenoh.ZError):
            open_session(
                ZenohSettings(
                    connect=router.endpoint,
                    zenoh_user="plant",
                    zenoh_password_file=tmp_path / "wrong",
                    connect_timeout_s=1.0,
                )
            )
        with router.session("viewer"):  # the right credentials do connect
            pass
        counts = router.stop()
    assert counts["logins_refused"].get("no credentials", 0) >= 1
    assert counts["logins_refused"].get("wrong password", 0) >= 1


@pytest.mark.in_process
def test_the_compose_router_file_is_the_generated_configuration():
    """docker/zenoh/router.json5 (what zenohd and the CI override run) is what the grants give, and parses."""
    text = (ROOT / "docker" / "zenoh" / "router.json5").read_text()
    access = RouterAccess(Path("/run/secrets/zenoh_users"))
    assert text == router_file_config(["tcp/0.0.0.0:7447"], access), "regenerate: windwarden router --print-config"
    zenoh.Config.from_file(str(ROOT / "docker" / "zenoh" / "router.json5"))


@pytest.mark.in_process
def test_no_two_roles_put_on_one_key():
    from windwarden.live.access import role_grants

    owners: dict[str, str] = {}
    for role, grants in role_grants(K).items():
        for grant in grants:
            if "put" in grant.messages and grant.flow == "ingress":
                for key in grant.keys:
                    assert owners.setdefault(key, role) == role, f"{key}: {owners[key]} and {role}"
    assert "viewer" not in owners.values() and "api" not in owners.values()


def test_router_refuses_to_start_without_credentials(tmp_path):
    with pytest.raises(ValueError):
        RouterAccess()
    bad = tmp_path / "users.txt"
    bad.write_text("plant-without-password\n")
    with pytest.raises(ValueError, match="user:password"):
        RouterAccess(bad).check()
    code = subprocess.run(
        [sys.executable, "-m", "windwarden.cli", "router", "--listen", "tcp/127.0.0.1:1"],
        capture_output=True,
        text=True,
        timeout=60,
        env=clean_env(),
    )
    assert code.returncode != 0 and "credentials" in code.stderr


@pytest.mark.in_process
def test_credentials_files_are_private(tmp_path):
    users = write_credentials(tmp_path / "c", new_passwords())
    assert (tmp_path / "c").stat().st_mode & 0o777 == 0o700
    for path in (tmp_path / "c").iterdir():
        assert path.stat().st_mode & 0o777 == 0o600, path
    lines = users.read_text().splitlines()
    assert [line.split(":")[0] for line in lines] == list(ROLES)


@pytest.mark.in_process
def test_audit_counts_only_dropped_messages():
    """A key's first use logs a decision for every message kind (nothing is dropped); a denial is a decision
    followed by 'Msg intercepted!' on the same thread (lines as zenoh 1.10.2 writes them)."""
    audit = RouterAudit(None)
    zid = "9470ea4f3582ff7bf181e0e69e3791cc"
    who = f"{zid} on Interface(lo)+Username(viewer)+Transport(Tcp)+{zid}"
    t1, t2 = "rx-1 ThreadId(09)", "rx-0 ThreadId(08)"
    lines = [
        f"TRACE {t1} zenoh::net::routing::interceptor::access_control: ACL (ingress): caching permissions for `k` ...",
        f"TRACE {t1} zenoh::net::routing::interceptor::access_control: {who} is unauthorized to Query (ingress) on k",
        f"TRACE {t1} zenoh::net::routing::interceptor::access_control: {who} is unauthorized to Put (ingress) on k",
        f"TRACE {t1} zenoh::net::routing::interceptor::access_control: {who} is authorized to Declare/Undeclare "
        "Subscriber (ingress) on k",
        f"TRACE {t1} zenoh::net::routing::interceptor::access_control: Using cached result: {zid} is authorized to "
        "Declare Subscriber (ingress) on k",
        f"TRACE {t2} zenoh::net::routing::interceptor::access_control: Using cached result: {zid} is unauthorized to "
        "Put (ingress) on k",
        f"TRACE {t1} zenoh::net::routing::interceptor::access_control: Using cached result: {zid} is authorized to "
        "Put (egress) on k",
        f"TRACE {t2} zenoh::net::routing::interceptor: Msg intercepted!",
        "DEBUG acc-0 ThreadId(05) zenoh_transport::unicast::establishment::accept: UsrPwd extension - Recv OpenSyn. "
        "Invalid password. at usrpwd.rs:424.",
    ]
    for line in lines:
        audit.feed("\x1b[2m2026-01-01T00:00:00Z\x1b[0m " + line + "\n")
    counts = audit.counts()
    assert counts["denied"] == [{"role": "viewer", "message": "put", "flow": "ingress", "key": "k", "count": 1}]
    assert counts["logins_refused"] == {"wrong password": 1}


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl to make the certificates")
def test_tls_client_certificates_identify_the_roles(tmp_path):
    certs = tmp_path / "certs"
    subprocess.run([str(ROOT / "tools" / "make_certs.sh"), str(certs)], check=True, capture_output=True, timeout=120)
    tls = TlsFiles(certs / "ca.pem", certs / "router.pem", certs / "router.key")
    from windwarden.live.router import free_port

    endpoint = f"tls/localhost:{free_port()}"

    def session(role: str | None) -> zenoh.Session:
        files = {}
        if role is not None:
            files = {"zenoh_tls_cert": certs / f"{role}.pem", "zenoh_tls_key": certs / f"{role}.key"}
        return open_session(
            ZenohSettings(connect=endpoint, zenoh_tls_ca=certs / "ca.pem", connect_timeout_s=2.0, **files)
        )

    with acl_router(tmp_path / "r", tls=tls, endpoint=endpoint) as router:
        with pytest.raises(zenoh.ZError):
            session(None)  # no client certificate
        plant, viewer, witness = session("plant"), session("viewer"), session("viewer")
        seen: list[bytes] = []
        witness.declare_subscriber(f"{K.base}/**", lambda s: seen.append(s.payload.to_bytes()))
        time.sleep(0.3)
        plant.put(K.sensors, b"from plant")
        viewer.put(K.refs("supervisor"), b"forged by viewer")
        assert wait_for(lambda: b"from plant" in seen, 5.0)
        time.sleep(SETTLE_S)
        assert b"forged by viewer" not in seen
        for s in (plant, viewer, witness):
            s.close()
        counts = router.stop()
    assert any(d["role"] == "viewer" and d["key"] == K.refs("supervisor") for d in counts["denied"]), json.dumps(counts)
