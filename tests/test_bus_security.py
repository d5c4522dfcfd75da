"""The secured bus: a real ``mstc router`` with per-mission credentials and the access control
derived from the schema refuses strangers and keeps each role to its own keys; TLS and mTLS
work on loopback; what the router cannot check (a robot id inside a message, a death
notice's detector and incarnation) the bus and the failure detector check."""

from __future__ import annotations

import os
import stat
import subprocess
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any, cast

import pytest
import zenoh
from conftest import pick_free_port

from bus import keys
from bus.bridge import Bus
from bus.codec import decode, encode
from bus.config import ConnectionSettings, TlsFiles, insert_values, make_zenoh_config
from bus.detector import FailureDetector
from bus.errors import ConfigError
from bus.messages import AdminCommand, AdminReply, DeathNotice, Heartbeat
from bus.messages.schema import ALIVE, FAMILIES
from bus.router import start_router_process, stop_process
from bus.security import acl, credentials
from bus.security.roles import OBSERVER, OPERATOR, SIMHW, parse_role, robot
from deploy.fleet import mstc_argv

MISSION = "sec"
ROOT = Path(__file__).resolve().parent.parent
MAKE_CERTS = ROOT / "scripts" / "make-certs.sh"
SETTLE = 0.5  # declarations reach the router and back


# --- credentials and rules (no network) ----------------------------------------------------

def test_credentials_file_is_private_and_round_trips(tmp_path: Path) -> None:
    creds = credentials.generate(MISSION, 3)
    path = tmp_path / credentials.CREDENTIALS_FILE
    creds.save(path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    loaded = credentials.load(path)
    assert loaded == creds
    assert [r.name for r in loaded.roles] == [
        "robot_0", "robot_1", "robot_2", "simhw", "operator", "observer", "router"]
    assert len(set(creds.passwords.values())) == 7
    assert creds.rotated().passwords.keys() == creds.passwords.keys()
    assert not set(creds.rotated().passwords.values()) & set(creds.passwords.values())
    assert creds.only(robot(1)).passwords == {"robot_1": creds.passwords["robot_1"]}


def test_credentials_readable_by_others_or_malformed_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "c.json"
    credentials.generate(MISSION, 1).save(path)
    os.chmod(path, 0o644)
    with pytest.raises(ConfigError, match="chmod 600"):
        credentials.load(path)
    path.write_text("{}")
    os.chmod(path, 0o600)
    with pytest.raises(ConfigError, match="not a mstc credentials file"):
        credentials.load(path)
    with pytest.raises(ConfigError, match="does not exist"):
        credentials.load(tmp_path / "missing.json")
    with pytest.raises(ConfigError, match="role"):
        ConnectionSettings(credentials=path)  # a client must say who it is


def test_tools_find_credentials_by_option_then_environment_then_run_directory(
        tmp_path: Path) -> None:
    (tmp_path / credentials.CREDENTIALS_FILE).write_text("x")
    given = tmp_path / "given.json"
    env = {credentials.ENV_CREDENTIALS: "/from/env.json"}
    assert credentials.locate(given, tmp_path, env) == given
    assert credentials.locate(None, tmp_path, env) == Path("/from/env.json")
    assert credentials.locate(None, tmp_path, {}) == tmp_path / credentials.CREDENTIALS_FILE
    assert credentials.locate(None, tmp_path / "nothing", {}) is None


def test_roles_parse_and_reject_unknown_names() -> None:
    assert parse_role("robot_12") == robot(12)
    assert parse_role("observer") == OBSERVER
    for bad in ("robot_-1", "robot_01", "root", "robot"):
        with pytest.raises(ConfigError):
            parse_role(bad)


def test_grants_follow_the_schema_access_column() -> None:
    r3 = acl.grants(robot(3), MISSION)
    assert keys.heartbeat(MISSION, 3) in r3["put"]
    assert keys.death(MISSION, 5).replace("/5", "/*") in r3["put"]  # death notices: any
    assert all("/5" not in key for key in r3["put"])
    assert r3["ask"].count(keys.hw_cmd(MISSION, 3)) == 1
    assert r3["token"] == [keys.of_robot("alive", MISSION, 3)]
    assert acl.grants(OBSERVER, MISSION).keys() == {"ask"}
    assert keys.hw_admin(MISSION) not in acl.grants(OBSERVER, MISSION)["ask"]
    assert keys.hw_admin(MISSION) in acl.grants(OPERATOR, MISSION)["ask"]
    assert keys.hw_admin(MISSION) in acl.grants(SIMHW, MISSION)["serve"]
    # every writable family is granted to some role, and nothing outside the mission is
    written = {key for role in (robot(0), SIMHW, OPERATOR, OBSERVER)
               for found in acl.grants(role, MISSION).values() for key in found}
    for fam in (*FAMILIES, ALIVE):
        if any(getattr(fam.access, verb) for verb in ("put", "serve", "ask", "token")):
            assert keys.of_robot(fam.label, MISSION, 0) in written \
                or keys.of_robot(fam.label, MISSION, None) in written, fam.label
    assert all(key.startswith(f"mstc/{MISSION}/") for key in written)


def test_advanced_publishers_are_allowed_where_their_family_is() -> None:
    r3, sim = acl.grants(robot(3), MISSION), acl.grants(SIMHW, MISSION)
    assert keys.progress(MISSION, 3) in r3["cache"]
    assert f"{keys.progress(MISSION, 3)}/@adv/**" in r3["advanced"]
    assert keys.heartbeat(MISSION, 3) not in r3["cache"]  # heartbeats are not recoverable
    assert all("/3" in key or "/*" in key or key.endswith("/mission") for key in r3["cache"])
    assert f"{keys.sim_cover(MISSION, 0).replace('/0', '/*')}/@adv/**" in sim["advanced"]
    assert "advanced" not in acl.grants(OBSERVER, MISSION)
    rules = {rule["id"]: rule for rule in acl.access_control(MISSION, [OBSERVER])["rules"]}
    assert rules["recover"]["key_exprs"] == [f"mstc/{MISSION}/**/@adv/**"]
    assert "put" not in rules["recover"]["messages"]


def test_a_message_about_another_robot_than_its_key_is_dropped_and_counted() -> None:
    bus = Bus(cast(Any, None), MISSION)
    forged = encode(Heartbeat(5, 1, 1, None, "running", 0.0))
    assert bus.decode_or_count(keys.heartbeat(MISSION, 3), forged, Heartbeat) is None
    assert bus.drops.total("hb", "robot_mismatch") == 1
    assert bus.decode_or_count(keys.heartbeat(MISSION, 5), forged, Heartbeat) is not None


def test_death_notices_need_a_known_detector_and_a_life_the_robot_had() -> None:
    fd = FailureDetector(detector=0)
    fd.on_token(1, 2, 0.0)
    fd.on_token(2, 1, 0.0)
    assert fd.notice_problem(DeathNotice(1, 2, None, "token", 0.0)) == "no detector"
    assert "participant" in str(fd.notice_problem(DeathNotice(1, 2, 9, "token", 0.0)))
    assert "never had" in str(fd.notice_problem(DeathNotice(1, 7, 2, "token", 0.0)))
    assert fd.notice_problem(DeathNotice(1, 2, 2, "token", 0.0)) is None
    assert fd.notice_problem(DeathNotice(1, 1, 2, "token", 0.0)) is None  # older life
    assert fd.notice_problem(DeathNotice(2, 1, 2, "leaving", 0.0)) is None
    # a dead detector's verdicts are re-announced by others and stay learnable
    assert fd.on_death_notice(DeathNotice(2, 1, 1, "token", 0.0))
    assert fd.notice_problem(DeathNotice(3, 1, 2, "token", 0.0)) is None
    # ... but not about a robot alive here, nor about this robot: across a healed partition
    # the far side's verdicts would stop the side that went on working
    assert "alive here" in str(fd.notice_problem(DeathNotice(1, 2, 2, "token", 0.0)))
    assert "is dead" in str(fd.notice_problem(DeathNotice(0, 1, 2, "token", 0.0)))
    assert fd.notice_problem(DeathNotice(0, 1, 1, "token", 0.0)) is None  # a live detector


# --- a real secured router ------------------------------------------------------------------

def _open(endpoint: str, creds: Path | None, role: str | None,
          tls: TlsFiles | None = None) -> zenoh.Session | None:
    """A client session, or None when the router refuses it (within 3 s)."""
    settings = ConnectionSettings(connect=(endpoint,), mission=MISSION, credentials=creds,
                                  role=role, tls=tls)
    config = make_zenoh_config(settings)
    insert_values(config, {"connect/timeout_ms": 3000, "connect/exit_on_failure": True})
    try:
        return zenoh.open(config)
    except zenoh.ZError:
        return None


class _Heard:
    def __init__(self, session: zenoh.Session, key: str) -> None:
        self.keys: list[str] = []
        self.payloads: list[bytes] = []
        self._lock = threading.Lock()
        self._sub = session.declare_subscriber(key, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        with self._lock:
            self.keys.append(str(sample.key_expr))
            self.payloads.append(sample.payload.to_bytes())

    def wait_for(self, key: str, timeout: float = 3.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                if key in self.keys:
                    return True
            time.sleep(0.02)
        return False


@pytest.fixture(scope="module")
def secure(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """(endpoint, credentials file) of a router enforcing mission "sec" with robots 0..5."""
    run_dir = tmp_path_factory.mktemp("run")
    path = run_dir / credentials.CREDENTIALS_FILE
    credentials.generate(MISSION, 6).save(path)
    endpoint = f"tcp/127.0.0.1:{pick_free_port()}"
    proc = start_router_process(endpoint, extra_args=("--credentials", str(path)))
    try:
        yield endpoint, path
    finally:
        stop_process(proc)


@pytest.fixture(scope="module")
def sessions(secure: tuple[str, Path]) -> Iterator[dict[str, zenoh.Session]]:
    endpoint, path = secure
    opened: dict[str, zenoh.Session] = {}
    for name in ("robot_0", "robot_3", "robot_5", "simhw", "operator", "observer"):
        session = _open(endpoint, path, name)
        assert session is not None, f"{name} refused with valid credentials"
        opened[name] = session
    try:
        yield opened
    finally:
        for session in opened.values():
            session.close()


@pytest.mark.slow
@pytest.mark.integration
def test_no_credentials_and_wrong_passwords_are_refused(
        secure: tuple[str, Path], tmp_path: Path) -> None:
    endpoint, path = secure
    assert _open(endpoint, None, None) is None
    wrong = tmp_path / "wrong.json"
    credentials.load(path).rotated().save(wrong)
    assert _open(endpoint, wrong, "robot_3") is None
    assert _open(endpoint, wrong, "observer") is None
    assert not list(path.parent.glob(".mstc-router-*")), "the router's dictionary outlived it"


@pytest.mark.integration
def test_an_observers_death_notice_reaches_nobody(sessions: dict[str, zenoh.Session]) -> None:
    heard = _Heard(sessions["robot_5"], keys.all_deaths(MISSION))
    time.sleep(SETTLE)
    notice = DeathNotice(3, 1, None, "token", 0.0)
    sessions["observer"].put(keys.death(MISSION, 3), encode(notice))
    sessions["robot_0"].put(keys.death(MISSION, 4), encode(DeathNotice(4, 1, 0, "token", 0.0)))
    assert heard.wait_for(keys.death(MISSION, 4)), "a robot's death notice got lost"
    time.sleep(0.2)
    assert keys.death(MISSION, 3) not in heard.keys


@pytest.mark.integration
def test_robot_3_cannot_publish_robot_5s_heartbeat(sessions: dict[str, zenoh.Session]) -> None:
    heard = _Heard(sessions["observer"], keys.all_heartbeats(MISSION))
    time.sleep(SETTLE)
    sessions["robot_3"].put(keys.heartbeat(MISSION, 5),
                            encode(Heartbeat(5, 1, 1, None, "running", 0.0)))
    sessions["robot_3"].put(keys.heartbeat(MISSION, 3),
                            encode(Heartbeat(3, 1, 1, None, "running", 0.0)))
    assert heard.wait_for(keys.heartbeat(MISSION, 3))
    time.sleep(0.2)
    assert keys.heartbeat(MISSION, 5) not in heard.keys


def _ask(session: zenoh.Session, key: str, payload: bytes | None = None) -> list[bytes]:
    replies = session.get(key, payload=payload, timeout=1.5)
    return [r.ok.payload.to_bytes() for r in replies if r.ok is not None]


@pytest.mark.integration
def test_only_the_operator_reaches_hw_admin_and_only_robot_i_its_body(
        sessions: dict[str, zenoh.Session]) -> None:
    reply = encode(AdminReply(True, "done"))
    admin = sessions["simhw"].declare_queryable(
        keys.hw_admin(MISSION), lambda q: q.reply(keys.hw_admin(MISSION), reply))
    body = sessions["simhw"].declare_queryable(
        keys.hw_cmd(MISSION, 5), lambda q: q.reply(keys.hw_cmd(MISSION, 5), b"ok"))
    try:
        time.sleep(SETTLE)
        request = encode(AdminCommand("fail", 3))
        got = _ask(sessions["operator"], keys.hw_admin(MISSION), request)
        assert [decode(p, AdminReply) for p in got] == [AdminReply(True, "done")]
        assert _ask(sessions["observer"], keys.hw_admin(MISSION), request) == []
        assert _ask(sessions["robot_3"], keys.hw_admin(MISSION), request) == []
        assert _ask(sessions["robot_5"], keys.hw_cmd(MISSION, 5)) == [b"ok"]
        assert _ask(sessions["robot_3"], keys.hw_cmd(MISSION, 5)) == []
    finally:
        admin.undeclare()
        body.undeclare()


@pytest.mark.integration
def test_an_observer_cannot_serve_state_or_declare_a_robots_token(
        sessions: dict[str, zenoh.Session]) -> None:
    fake = sessions["observer"].declare_queryable(
        keys.state(MISSION, 5), lambda q: q.reply(keys.state(MISSION, 5), b"lie"))
    token = sessions["observer"].liveliness().declare_token(keys.alive(MISSION, 5, 1))
    try:
        time.sleep(SETTLE)
        assert _ask(sessions["robot_0"], keys.all_states(MISSION)) == []
        tokens = sessions["robot_0"].liveliness().get(keys.all_alive(MISSION), timeout=1.0)
        assert [r.ok for r in tokens if r.ok is not None] == []
    finally:
        fake.undeclare()
        token.undeclare()


# --- TLS ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(certificates of the deployment, those of another CA)."""
    good, wrong = tmp_path_factory.mktemp("pki"), tmp_path_factory.mktemp("wrong")
    subprocess.run([str(MAKE_CERTS), str(good), "--client", "robot_3", "--client", "observer"],
                   check=True, capture_output=True)
    subprocess.run([str(MAKE_CERTS), str(wrong), "--client", "robot_3"], check=True,
                   capture_output=True)
    return good, wrong


@pytest.mark.integration
@pytest.mark.slow  # over 10 s: CI runs it, the quick loop does not
def test_mtls_with_credentials_works_on_loopback_and_refuses_a_wrong_ca(
        certs: tuple[Path, Path], tmp_path: Path) -> None:
    good, wrong = certs
    path = tmp_path / credentials.CREDENTIALS_FILE
    credentials.generate(MISSION, 4).save(path)
    endpoint = f"tls/localhost:{pick_free_port()}"
    proc = start_router_process(endpoint, extra_args=(
        "--credentials", str(path), "--tls-ca", str(good / "ca.pem"),
        "--tls-cert", str(good / "router.pem"), "--tls-key", str(good / "router.key"),
        "--mtls"))
    mine = TlsFiles(good / "ca.pem", good / "robot_3.pem", good / "robot_3.key")
    opened: list[zenoh.Session] = []
    try:
        assert _open(endpoint, path, "robot_3", replace(mine, ca=wrong / "ca.pem")) is None
        assert _open(endpoint, path, "robot_3", TlsFiles(
            good / "ca.pem", wrong / "robot_3.pem", wrong / "robot_3.key")) is None
        assert _open(endpoint, path, "robot_3", TlsFiles(good / "ca.pem")) is None  # no cert
        listener = _open(endpoint, path, "observer",
                         TlsFiles(good / "ca.pem", good / "observer.pem", good / "observer.key"))
        robot3 = _open(endpoint, path, "robot_3", mine)
        assert listener is not None and robot3 is not None
        opened += [listener, robot3]
        heard = _Heard(listener, keys.all_heartbeats(MISSION))
        time.sleep(SETTLE)
        # robot_3's password with the observer's certificate: the rules need both to name
        # the role, so it gets the rights of neither
        mixed = _open(endpoint, path, "robot_3",
                      TlsFiles(good / "ca.pem", good / "observer.pem", good / "observer.key"))
        assert mixed is not None
        opened.append(mixed)
        time.sleep(SETTLE)
        mixed.put(keys.heartbeat(MISSION, 3), encode(Heartbeat(3, 1, 9, None, "ok", 0.0)))
        robot3.put(keys.heartbeat(MISSION, 3), encode(Heartbeat(3, 1, 1, None, "ok", 0.0)))
        assert heard.wait_for(keys.heartbeat(MISSION, 3)), "nothing travels over mTLS"
        time.sleep(0.3)
        assert [decode(p, Heartbeat).seq for p in heard.payloads] == [1], \
            "a mixed identity could publish"
    finally:
        for session in opened:
            session.close()
        stop_process(proc)


def test_tls_files_must_exist_and_pair(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        TlsFiles(tmp_path / "ca.pem")
    (tmp_path / "ca.pem").write_text("x")
    with pytest.raises(ConfigError, match="together"):
        TlsFiles(tmp_path / "ca.pem", cert=tmp_path / "ca.pem")


def _put_until_heard(session: zenoh.Session, heard: _Heard, key: str, seq: int,
                     timeout: float = 8.0) -> bool:
    """Heartbeats on ``key`` every 0.1 s until ``heard`` has one (a joined router's
    routes come up a moment after it says it is ready)."""
    robot_id = int(key.rsplit("/", 1)[1])
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        session.put(key, encode(Heartbeat(robot_id, 1, seq, None, "ok", 0.0)))
        if heard.wait_for(key, 0.1):
            return True
    return False


@pytest.mark.integration
@pytest.mark.slow  # two routers and five TLS sessions: CI runs it, the quick loop does not
def test_two_secured_routers_join_over_mtls_and_keep_every_role_to_its_keys(
        tmp_path: Path) -> None:
    # Each router checks the roles that logged in to it; the link between them carries the
    # mission both ways because each recognises the other by the router certificate.
    pki = tmp_path / "pki"
    subprocess.run([str(MAKE_CERTS), str(pki), "--client", "robot_3", "--client", "robot_5",
                    "--client", "observer"], check=True, capture_output=True)
    path = tmp_path / credentials.CREDENTIALS_FILE
    credentials.generate(MISSION, 6).save(path)
    router_tls = ("--credentials", str(path), "--tls-ca", str(pki / "ca.pem"),
                  "--tls-cert", str(pki / "router.pem"), "--tls-key", str(pki / "router.key"))
    hub = f"tls/localhost:{pick_free_port()}"
    joined = f"tls/localhost:{pick_free_port()}"

    # Without mTLS a secured router refuses to join: the other side could not know it.
    refused = subprocess.run(
        mstc_argv("router", "--listen", joined, "--connect", hub, *router_tls),
        capture_output=True, text=True, timeout=30, check=False)
    assert refused.returncode == 2 and "only over mTLS" in refused.stderr, refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1

    procs = [start_router_process(hub, extra_args=(*router_tls, "--mtls"))]
    opened: list[zenoh.Session] = []
    try:
        procs.append(start_router_process(joined, extra_args=(
            "--connect", hub, *router_tls, "--mtls")))

        def session(endpoint: str, role: str) -> zenoh.Session:
            found = _open(endpoint, path, role,
                          TlsFiles(pki / "ca.pem", pki / f"{role}.pem", pki / f"{role}.key"))
            assert found is not None, f"{role} refused at {endpoint}"
            opened.append(found)
            return found

        near_observer, far_observer = session(hub, "observer"), session(joined, "observer")
        near_robot, far_robot = session(hub, "robot_3"), session(joined, "robot_5")
        heard_far = _Heard(far_observer, keys.all_heartbeats(MISSION))
        heard_near = _Heard(near_observer, keys.all_heartbeats(MISSION))
        assert _put_until_heard(near_robot, heard_far, keys.heartbeat(MISSION, 3), 1), \
            "nothing crosses from the hub to the joined router"
        assert _put_until_heard(far_robot, heard_near, keys.heartbeat(MISSION, 5), 1), \
            "nothing crosses from the joined router to the hub"
        # robot 5 writing robot 3's key at its own router reaches neither side
        before = (len(heard_near.payloads), len(heard_far.payloads))
        for _ in range(5):
            far_robot.put(keys.heartbeat(MISSION, 3), encode(Heartbeat(3, 1, 99, None, "ok",
                                                                        0.0)))
        near_robot.put(keys.heartbeat(MISSION, 3), encode(Heartbeat(3, 1, 2, None, "ok", 0.0)))
        deadline = time.monotonic() + 3.0  # the witness: robot 3's own next heartbeat
        while time.monotonic() < deadline and not any(
                decode(p, Heartbeat).seq == 2 for p in heard_far.payloads):
            time.sleep(0.02)
        assert any(decode(p, Heartbeat).seq == 2 for p in heard_far.payloads)
        forged = [decode(p, Heartbeat).seq for p in
                  heard_near.payloads[before[0]:] + heard_far.payloads[before[1]:]]
        assert 99 not in forged, "a robot wrote another's key across the routers"
    finally:
        for opened_session in opened:
            opened_session.close()
        for proc in procs:
            stop_process(proc)

