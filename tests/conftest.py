"""Shared fixtures: a free loopback port, and a real ``mstc router`` subprocess."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest


def pick_free_port() -> int:
    """A TCP port free on 127.0.0.1 right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.fixture
def free_port() -> int:
    return pick_free_port()


@pytest.fixture(scope="module")
def router() -> Iterator[str]:
    """Endpoint (tcp/127.0.0.1:<port>) of an ``mstc router`` subprocess, one per module."""
    from bus.router import start_router_process, stop_process

    endpoint = f"tcp/127.0.0.1:{pick_free_port()}"
    proc = start_router_process(endpoint)
    try:
        yield endpoint
    finally:
        stop_process(proc)
