"""Shared fixtures (a free loopback port, a real ``mstc router`` subprocess) and the
hypothesis profiles: ``default`` for CI, ``quick`` for the edit-test loop."""

from __future__ import annotations

import compileall
import os
import socket
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

# The quick loop (README, Development) runs every property with few examples: enough to
# catch a broken invariant while editing; CI keeps each test's own max_examples.
QUICK_EXAMPLES = 10
settings.register_profile("quick", max_examples=QUICK_EXAMPLES)


# The packages every fleet process imports. A test session starts hundreds of Python
# processes (router, simhw, agents, launchers); where PYTHONDONTWRITEBYTECODE is set (the
# development machine sets it) each of them would compile ~250 modules from source, about
# 0.17 s of CPU a process (docs/testing.md, "Where the suite's time goes").
PROJECT_PACKAGES = ("agent", "bus", "deploy", "planner", "simhw")


def pytest_configure(config: pytest.Config) -> None:
    if hasattr(config, "workerinput") or not sys.dont_write_bytecode:
        return  # xdist workers: the controller did it; otherwise imports write their own
    root = Path(__file__).resolve().parent.parent
    for package in PROJECT_PACKAGES:
        compileall.compile_dir(root / package, quiet=1)


@pytest.hookimpl(wrapper=True)
def pytest_collection(session: pytest.Session) -> object:
    """Keep pytest's rewritten test modules (``tests/__pycache__/*-pytest-*.pyc``) even where
    PYTHONDONTWRITEBYTECODE is set. pytest honours that variable by rewriting every test
    module's asserts from source at each run, in each xdist worker: a collection took
    7.1-7.6 s with the rewriting and 3.4 s without (docs/testing.md). Only the collection
    writes bytecode; the variable holds again for everything the tests import later."""
    saved = sys.dont_write_bytecode
    sys.dont_write_bytecode = False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = saved


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto`` starts three workers for two cores. The integration tests wait on real
    time (missions at time scale 1, leases, timeouts) as much as they compute: with one
    worker per core the suite kept the cores busy 67 % of its run, and a third worker took
    the full suite from 616 s to 523-529 s on 2 cores (docs/testing.md). The tests hold
    under the extra load by design (each was run beside busy loops). A number in
    ``PYTEST_XDIST_AUTO_NUM_WORKERS`` still decides (xdist's own hook reads it)."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None
    cores = len(os.sched_getaffinity(0))
    return max(2, cores * 3 // 2)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    # A test's own @settings(max_examples=N) beats any profile, so the quick profile
    # lowers each test's settings itself; hypothesis reads them when the test runs.
    if settings.get_current_profile_name() != "quick":
        return
    for item in items:
        test = getattr(getattr(item, "obj", None), "__func__", getattr(item, "obj", None))
        own = getattr(test, "_hypothesis_internal_use_settings", None)
        if own is not None and own.max_examples > QUICK_EXAMPLES:
            test._hypothesis_internal_use_settings = settings(  # type: ignore[union-attr]
                own, max_examples=QUICK_EXAMPLES)


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
