"""An embedded Zenoh router: a session in router mode held open until asked to stop.

Given credentials it admits only their roles and enforces the mission's access control
(bus.security.acl); the user:password dictionary Zenoh reads is a private temporary file
that exists only while the router starts.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType

import zenoh

from bus.config import ConnectionSettings, insert_values, make_zenoh_config
from bus.errors import RouterError
from bus.security import acl, credentials


class StopSignals:
    """SIGTERM and SIGINT as a flag that a serving loop polls (``stop_signals()`` is true
    once one came).

    The handler only records the signal. Python runs handlers in the main thread between
    two bytecodes, possibly while that thread holds a lock inside ``threading.Event.wait``:
    a handler that set an Event waited for that lock for ever. A router signalled at such
    a moment never exited (a test run left one behind, its main thread blocked in
    ``Event.set`` inside the handler, inside ``Event.wait``).
    """

    SIGNALS = (signal.SIGTERM, signal.SIGINT)

    def __init__(self) -> None:
        self.received: list[int] = []

    def install(self) -> None:
        for sig in self.SIGNALS:
            signal.signal(sig, self._on_signal)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.received.append(signum)  # list.append takes no Python-level lock

    def __call__(self) -> bool:
        return bool(self.received)


def run_router(settings: ConnectionSettings, stopping: Callable[[], bool],
               ready: Callable[[], None] | None = None, parent: int | None = None) -> None:
    """Serve as a router on ``settings.listen`` until ``stopping()`` is true (or, if
    ``parent`` is given, until that process is no longer our parent); RouterError if the
    router cannot start (typically: the listen port is taken)."""
    if settings.mode != "router":
        raise RouterError(f"run_router needs mode 'router', got {settings.mode!r}")
    config = make_zenoh_config(settings)
    # exit_on_failure makes a taken port a start-up error instead of a silent retry loop.
    config.insert_json5("listen/exit_on_failure", "true")
    with _dictionary(settings) as secured:
        if secured is not None:
            creds, dictionary = secured
            mtls = settings.tls is not None and settings.tls.mtls
            insert_values(config, acl.router_values(creds, dictionary, by_certificate=mtls))
        try:
            session = zenoh.open(config)
        except zenoh.ZError as error:
            raise RouterError(f"cannot listen on {', '.join(settings.listen)}: "
                              f"{_short(str(error))}") from error
    try:
        if ready is not None:
            ready()
        while not stopping():
            if parent is not None and os.getppid() != parent:
                break
            time.sleep(STOP_POLL_S)
    finally:
        _close_within(session, CLOSE_TIMEOUT_S)


# How often the serving loop looks for a stop (a signal, or its parent gone).
STOP_POLL_S = 0.2

# A router holds nothing to flush; a close that has not returned by then is given up on (seen
# once in a CI rehearsal: a router signalled right after start-up never exited).
CLOSE_TIMEOUT_S = 5.0


def _close_within(session: zenoh.Session, timeout: float) -> None:
    closer = threading.Thread(target=session.close, name="router-close", daemon=True)
    closer.start()
    closer.join(timeout)


@contextmanager
def _dictionary(
        settings: ConnectionSettings) -> Iterator[tuple[credentials.Credentials, Path] | None]:
    """Zenoh reads its user:password dictionary from a file, once, at start-up."""
    if settings.credentials is None:
        yield None
        return
    creds = credentials.load(settings.credentials)
    fd, name = tempfile.mkstemp(prefix=".mstc-router-", suffix=".dict",
                                dir=settings.credentials.parent)
    path = Path(name)
    try:
        with os.fdopen(fd, "w") as out:
            out.write(creds.dictionary())
        yield creds, path
    finally:
        path.unlink(missing_ok=True)


def _short(message: str) -> str:
    """Zenoh errors carry Rust source locations; keep the first sentence for the user."""
    if "Address already in use" in message:
        return "address already in use (is another router running?)"
    head = message.split(" at /", 1)[0]
    return head.replace("\n", " ").strip()


READY_MARK = "mstc router: ready"


def start_router_process(endpoint: str, *, timeout: float = 10.0,
                         extra_args: tuple[str, ...] = ()) -> subprocess.Popen[str]:
    """Start ``mstc router --listen endpoint`` as a child process (never a fork of this
    one) and return once it says it is ready; RouterError with its message if it fails."""
    command = [sys.executable, "-m", "deploy.cli", "router", "--listen", endpoint,
               "--exit-with-parent", *extra_args]
    proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        readable, _, _ = select.select([proc.stdout], [], [], 0.1)
        if readable:
            line = proc.stdout.readline()
            if line.startswith(READY_MARK):
                return proc
            if not line:  # EOF: the router exited
                break
    if proc.poll() is None:
        proc.kill()
    assert proc.stderr is not None
    err = proc.stderr.read().strip()
    stop_process(proc)
    raise RouterError(err or f"router on {endpoint} did not start within {timeout:.0f} s")


def stop_process(proc: subprocess.Popen[str], timeout: float = 5.0) -> int:
    """SIGTERM, then SIGKILL after ``timeout``; return the exit code."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    for stream in (proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()
    return int(proc.returncode)
