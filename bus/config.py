"""Zenoh session set-up for every process, from one place.

Command line options (with environment fallbacks) become a frozen ConnectionSettings, which
becomes a zenoh.Config. Defaults: client mode to a router on tcp/127.0.0.1:7447, waiting for
the router forever so processes may start in any order, multicast scouting off (loopback
only), and a 1 s transport lease so a hung (SIGSTOPped) process's tokens expire in ~0.75 s
instead of ~7.5 s (docs/protocol.md, "Liveness").

With ``credentials`` a client logs in as its ``role`` (docs/security.md); with ``tls`` it
verifies the router's certificate against the CA and, given its own certificate, presents
it (mTLS). The router's side of both is in bus.router.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import logging
import os
import sys
import threading
from collections.abc import AsyncIterator, Callable, Iterator, Mapping
from contextlib import asynccontextmanager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, cast

import zenoh

from bus.errors import ConfigError, KeyExprError
from bus.keys import check_mission
from bus.security import credentials
from bus.security.credentials import ENV_CREDENTIALS, ENV_ROLE
from bus.security.roles import ROUTER, parse_role

_log = logging.getLogger("mstc.bus")

Mode = Literal["client", "peer", "router"]
MODES: tuple[Mode, ...] = ("client", "peer", "router")
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
DEFAULT_MISSION = "default"
# Measured: a hung process's token expires after ~0.75 x the lease it announced; 1 s keeps
# that under a second while staying well clear of the 100-500 ms leases where start-up
# storms are known to cause false expiries elsewhere (ROS 2 rmw_zenoh).
DEFAULT_LEASE_MS = 1000
RETRY_PERIOD_MS = 250

ENV_CONNECT = "MSTC_CONNECT"
ENV_LISTEN = "MSTC_LISTEN"
ENV_MODE = "MSTC_MODE"
ENV_ZENOH_CONFIG = "MSTC_ZENOH_CONFIG"
ENV_MISSION = "MSTC_MISSION"
ENV_LEASE_MS = "MSTC_LEASE_MS"
ENV_TLS_CA = "MSTC_TLS_CA"
ENV_TLS_CERT = "MSTC_TLS_CERT"
ENV_TLS_KEY = "MSTC_TLS_KEY"


@dataclass(frozen=True)
class TlsFiles:
    """PEM files for tls/ endpoints: the CA that signed the other side's certificate, and
    this side's certificate and key (the router's own; a client's for mTLS). ``mtls`` on a
    router refuses clients without a certificate of that CA."""

    ca: Path
    cert: Path | None = None
    key: Path | None = None
    mtls: bool = False

    def __post_init__(self) -> None:
        if (self.cert is None) != (self.key is None):
            raise ConfigError("a TLS certificate and its key go together")
        for path in (self.ca, self.cert, self.key):
            if path is not None and not path.is_file():
                raise ConfigError(f"TLS file {path} does not exist")


@dataclass(frozen=True)
class ConnectionSettings:
    """How one process joins the Zenoh network. Empty ``connect`` in client mode means
    the default router endpoint."""

    mode: Mode = "client"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    zenoh_config: Path | None = None
    mission: str = DEFAULT_MISSION
    lease_ms: int = DEFAULT_LEASE_MS
    credentials: Path | None = None
    role: str | None = None
    tls: TlsFiles | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if self.lease_ms < 100:
            raise ConfigError(f"lease must be at least 100 ms, got {self.lease_ms}")
        for endpoint in self.connect + self.listen:
            _check_endpoint(endpoint)
        try:
            check_mission(self.mission)
        except KeyExprError as error:
            raise ConfigError(str(error)) from error
        if self.credentials is not None and self.mode != "router" and self.role is None:
            raise ConfigError("credentials need a role (--role robot_<id>, simhw, operator "
                              "or observer)")
        if self.role is not None:
            parse_role(self.role)

    @property
    def secure(self) -> bool:
        return self.credentials is not None

    @property
    def endpoints(self) -> tuple[str, ...]:
        """The endpoints this process connects to (the default router in client mode)."""
        if self.connect or self.mode != "client":
            return self.connect
        return (DEFAULT_ENDPOINT,)


def _check_endpoint(endpoint: str) -> None:
    proto, sep, address = endpoint.partition("/")
    if not sep or not proto or not address:
        raise ConfigError(f"endpoint {endpoint!r} must look like tcp/127.0.0.1:7447")


def _split_env(value: str | None) -> list[str]:
    return [part.strip() for part in (value or "").split(",") if part.strip()]


def add_connection_arguments(parser: argparse.ArgumentParser,
                             env: Mapping[str, str] | None = None) -> None:
    """Add --connect/--listen/--mode/--zenoh-config/--mission/--lease-ms and the security
    options (--credentials/--role/--tls-*) to ``parser``. Environment variables
    (MSTC_CONNECT and MSTC_LISTEN comma-separated) give defaults."""
    env = os.environ if env is None else env
    group = parser.add_argument_group("Zenoh connection")
    group.add_argument("--connect", action="append", metavar="ENDPOINT",
                       default=_split_env(env.get(ENV_CONNECT)) or None,
                       help=f"router/peer endpoint to connect to (repeatable; "
                            f"default {DEFAULT_ENDPOINT} in client mode; env {ENV_CONNECT})")
    group.add_argument("--listen", action="append", metavar="ENDPOINT",
                       default=_split_env(env.get(ENV_LISTEN)) or None,
                       help=f"endpoint to listen on (repeatable; env {ENV_LISTEN})")
    group.add_argument("--mode", choices=MODES, default=env.get(ENV_MODE, "client"),
                       help=f"Zenoh session mode (default client; env {ENV_MODE})")
    group.add_argument("--zenoh-config", metavar="FILE", type=Path,
                       default=env.get(ENV_ZENOH_CONFIG) or None,
                       help=f"json5 Zenoh config applied before these options "
                            f"(env {ENV_ZENOH_CONFIG})")
    group.add_argument("--mission", default=env.get(ENV_MISSION, DEFAULT_MISSION),
                       help=f"mission namespace in every key (default {DEFAULT_MISSION}; "
                            f"env {ENV_MISSION})")
    group.add_argument("--lease-ms", type=int,
                       default=int(env.get(ENV_LEASE_MS, DEFAULT_LEASE_MS)),
                       help=f"transport lease in ms: a hung process is dropped after "
                            f"~0.75 x this (default {DEFAULT_LEASE_MS}; env {ENV_LEASE_MS})")
    add_security_arguments(parser, env)


def add_security_arguments(parser: argparse.ArgumentParser,
                           env: Mapping[str, str] | None = None) -> None:
    env = os.environ if env is None else env
    group = parser.add_argument_group("Zenoh security (docs/security.md)")
    group.add_argument("--credentials", metavar="FILE", type=Path,
                       default=env.get(ENV_CREDENTIALS) or None,
                       help=f"mission credentials file (JSON, mode 0600; env "
                            f"{ENV_CREDENTIALS}); a router enforces them, a client logs in")
    group.add_argument("--role", default=env.get(ENV_ROLE) or None,
                       help=f"role to log in as: robot_<id>, simhw, operator, observer or router "
                            f"(env {ENV_ROLE})")
    group.add_argument("--tls-ca", metavar="PEM", type=Path,
                       default=env.get(ENV_TLS_CA) or None,
                       help=f"CA certificate for tls/ endpoints (env {ENV_TLS_CA})")
    group.add_argument("--tls-cert", metavar="PEM", type=Path,
                       default=env.get(ENV_TLS_CERT) or None,
                       help=f"this process's certificate: the router's, or a client's for "
                            f"mTLS (env {ENV_TLS_CERT})")
    group.add_argument("--tls-key", metavar="PEM", type=Path,
                       default=env.get(ENV_TLS_KEY) or None,
                       help=f"the key of --tls-cert (env {ENV_TLS_KEY})")
    group.add_argument("--mtls", action="store_true",
                       help="router: refuse clients without a certificate of the CA; their "
                            "certificate's common name must be their role")


def tls_from_args(args: argparse.Namespace) -> TlsFiles | None:
    ca = getattr(args, "tls_ca", None)
    if ca is None:
        if getattr(args, "tls_cert", None) or getattr(args, "mtls", False):
            raise ConfigError("TLS needs --tls-ca")
        return None
    return TlsFiles(Path(ca), _path(args.tls_cert), _path(args.tls_key), bool(args.mtls))


def _path(value: object) -> Path | None:
    return None if value is None else Path(str(value))


def settings_from_args(args: argparse.Namespace,
                       default_role: str | None = None) -> ConnectionSettings:
    """Build ConnectionSettings from the options added by add_connection_arguments;
    ``default_role`` is the role of this kind of process when --role is not given."""
    return ConnectionSettings(
        mode=cast(Mode, args.mode),
        connect=tuple(args.connect or ()),
        listen=tuple(args.listen or ()),
        zenoh_config=Path(args.zenoh_config) if args.zenoh_config else None,
        mission=args.mission,
        lease_ms=int(args.lease_ms),
        credentials=_path(getattr(args, "credentials", None)),
        role=getattr(args, "role", None) or default_role,
        tls=tls_from_args(args),
    )


def _base_config(path: Path | None) -> zenoh.Config:
    if path is None:
        return zenoh.Config()
    if not path.is_file():
        raise ConfigError(f"Zenoh config file {path} does not exist")
    try:
        return zenoh.Config.from_file(str(path))
    except zenoh.ZError as error:
        raise ConfigError(f"cannot load Zenoh config {path}: {error}") from error


def make_zenoh_config(settings: ConnectionSettings) -> zenoh.Config:
    """A zenoh.Config for ``settings``; a --zenoh-config file is the base, options override."""
    config = _base_config(settings.zenoh_config)
    values: dict[str, object] = {
        "mode": settings.mode,
        "scouting/multicast/enabled": False,
        "transport/link/tx/lease": settings.lease_ms,
        # Wait for the router forever instead of failing at once: start order is free.
        "connect/timeout_ms": -1,
        "connect/exit_on_failure": False,
        "connect/retry": {"period_init_ms": RETRY_PERIOD_MS, "period_max_ms": 1000,
                          "period_increase_factor": 2},
    }
    if settings.endpoints:
        values["connect/endpoints"] = list(settings.endpoints)
    if settings.listen:
        values["listen/endpoints"] = list(settings.listen)
    elif settings.mode == "peer":
        # A peer must still listen somewhere for others to reach it; loopback only.
        values["listen/endpoints"] = ["tcp/127.0.0.1:0"]
    values.update(_security_values(settings))
    insert_values(config, values)
    return config


def insert_values(config: zenoh.Config, values: Mapping[str, object]) -> None:
    for key, value in values.items():
        try:
            config.insert_json5(key, json.dumps(value))
        except zenoh.ZError as error:
            raise ConfigError(f"invalid Zenoh setting {key}={value!r}: {error}") from error


def _security_values(settings: ConnectionSettings) -> dict[str, object]:
    values: dict[str, object] = {}
    if settings.credentials is not None and settings.mode != "router":
        assert settings.role is not None  # checked by ConnectionSettings
        role = parse_role(settings.role)
        creds = credentials.load(settings.credentials)
        if creds.mission != settings.mission:
            raise ConfigError(f"credentials file {settings.credentials} is for mission "
                              f"{creds.mission!r}, not {settings.mission!r}")
        values["transport/auth/usrpwd/user"] = role.name
        values["transport/auth/usrpwd/password"] = creds.password(role)
    joining = settings.mode == "router" and bool(settings.connect)
    if settings.credentials is not None and joining:
        _check_secure_join(settings)
        creds = credentials.load(settings.credentials)
        values["transport/auth/usrpwd/user"] = ROUTER.name
        values["transport/auth/usrpwd/password"] = creds.password(ROUTER)
    tls = settings.tls
    if tls is not None:
        side = "listen" if settings.mode == "router" else "connect"
        values["transport/link/tls/root_ca_certificate"] = str(tls.ca)
        if tls.cert is not None and tls.key is not None:
            values[f"transport/link/tls/{side}_certificate"] = str(tls.cert)
            values[f"transport/link/tls/{side}_private_key"] = str(tls.key)
            if joining:  # the router certificate serves both ways (scripts/make-certs.sh)
                values["transport/link/tls/connect_certificate"] = str(tls.cert)
                values["transport/link/tls/connect_private_key"] = str(tls.key)
        values["transport/link/tls/enable_mtls"] = tls.mtls if side == "listen" \
            else tls.cert is not None
    return values


def _check_secure_join(settings: ConnectionSettings) -> None:
    """A secured router joins another only over mTLS: the two recognise each other by the
    router certificate (bus.security.acl), and the one joined never logs in to the other."""
    tls = settings.tls
    if tls is None or not tls.mtls or tls.cert is None or tls.key is None:
        raise ConfigError("a secured router joins another only over mTLS: add --tls-ca, "
                          "--tls-cert and --tls-key of the router certificate and --mtls "
                          "(docs/security.md, 'Several hosts')")
    plain = [e for e in settings.connect if not e.startswith("tls/")]
    if plain:
        raise ConfigError(f"a secured router joins another over tls/ endpoints, not "
                          f"{', '.join(plain)}")


# Zenoh's threads take the GIL to hand each sample to the loop. With CPython's default 5 ms
# switch interval a busy loop thread lets them in about 200 times a second; a session that
# reads that slowly fills the router's queue towards it, and the router then holds back
# every publisher's BLOCK traffic (docs/architecture.md, "Sessions that read slowly").
GIL_SWITCH_INTERVAL_S = 0.0002


def _hand_samples_over_promptly() -> None:
    if sys.getswitchinterval() > GIL_SWITCH_INTERVAL_S:
        sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)


class _Opener:
    """Runs the blocking ``zenoh.open`` (it waits for the router forever) in a daemon thread
    so the caller stays responsive to Ctrl-C and cancellation; a session that arrives after
    its caller gave up is closed by the thread itself."""

    def __init__(self, config: zenoh.Config) -> None:
        _hand_samples_over_promptly()
        self.done = threading.Event()
        self.session: zenoh.Session | None = None
        self.error: zenoh.ZError | None = None
        self._abandoned = False
        self._lock = threading.Lock()
        self._on_done: Callable[[], None] | None = None
        threading.Thread(target=self._run, args=(config,), name="zenoh-open",
                         daemon=True).start()

    def _run(self, config: zenoh.Config) -> None:
        try:
            session = zenoh.open(config)
        except zenoh.ZError as error:
            self.error = error
            session = None
        with self._lock:
            abandoned = self._abandoned
            self.session = session
            self.done.set()
            notify = self._on_done
        if abandoned and session is not None:
            session.close()
        elif notify is not None:
            notify()

    def notify(self, callback: Callable[[], None]) -> None:
        with self._lock:
            self._on_done = callback
            already = self.done.is_set()
        if already:
            callback()

    def abandon(self) -> None:
        with self._lock:
            self._abandoned = True
            session = self.session if self.done.is_set() else None
        if session is not None:
            session.close()

    def result(self) -> zenoh.Session:
        if self.error is not None:
            raise ConfigError(f"cannot open Zenoh session: {self.error}") from self.error
        assert self.session is not None
        return self.session


def _waiting_note(settings: ConnectionSettings) -> None:
    # Zenoh reports a refused log-in like an absent router: say so, or a wrong password
    # looks like a router that never came up.
    refused = (f" (or it refuses role {settings.role} with {settings.credentials})"
               if settings.secure else "")
    _log.info("waiting for a Zenoh router at %s%s", ", ".join(settings.endpoints) or "-",
              refused)


@contextmanager
def open_session(settings: ConnectionSettings) -> Iterator[zenoh.Session]:
    """Open a Zenoh session (waiting for the router as long as it takes, interruptibly)
    and always close it: an unclosed session hangs Python's exit."""
    opener = _Opener(make_zenoh_config(settings))
    try:
        if not opener.done.wait(1.0):
            _waiting_note(settings)
            while not opener.done.wait(0.2):
                pass
    except BaseException:
        opener.abandon()
        raise
    session = opener.result()
    try:
        yield session
    finally:
        session.close()


@asynccontextmanager
async def open_session_async(settings: ConnectionSettings) -> AsyncIterator[zenoh.Session]:
    """open_session for asyncio code: the loop keeps running while the router is awaited."""
    loop = asyncio.get_running_loop()
    ready = loop.create_future()
    opener = _Opener(make_zenoh_config(settings))

    def resolve() -> None:
        if not ready.done():
            ready.set_result(None)

    def on_done() -> None:
        with contextlib.suppress(RuntimeError):  # loop closed: the caller is gone
            loop.call_soon_threadsafe(resolve)

    opener.notify(on_done)
    try:
        try:
            await asyncio.wait_for(asyncio.shield(ready), 1.0)
        except TimeoutError:
            _waiting_note(settings)
            await ready
    except BaseException:
        opener.abandon()
        raise
    session = opener.result()
    try:
        yield session
    finally:
        session.close()
