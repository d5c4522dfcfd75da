"""Connection settings, Zenoh config generation, and the ``mstc router`` command."""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from bus.config import (
    DEFAULT_ENDPOINT,
    DEFAULT_LEASE_MS,
    ConnectionSettings,
    add_connection_arguments,
    make_zenoh_config,
    settings_from_args,
)
from bus.errors import ConfigError, RouterError
from bus.router import start_router_process, stop_process


def parse(argv: list[str], env: dict[str, str] | None = None) -> ConnectionSettings:
    parser = argparse.ArgumentParser()
    add_connection_arguments(parser, env=env or {})
    return settings_from_args(parser.parse_args(argv))


def test_defaults_are_a_waiting_loopback_client() -> None:
    settings = parse([])
    assert settings == ConnectionSettings()
    assert settings.endpoints == (DEFAULT_ENDPOINT,)
    config = make_zenoh_config(settings)
    assert json.loads(config.get_json("mode")) == "client"
    assert json.loads(config.get_json("connect/endpoints")) == [DEFAULT_ENDPOINT]
    assert json.loads(config.get_json("connect/timeout_ms")) == -1
    assert json.loads(config.get_json("connect/exit_on_failure")) is False
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("transport/link/tx/lease")) == DEFAULT_LEASE_MS


def test_options_and_environment() -> None:
    env = {"MSTC_CONNECT": "tcp/127.0.0.1:1, tcp/127.0.0.1:2", "MSTC_MODE": "peer",
           "MSTC_MISSION": "envmission", "MSTC_LEASE_MS": "500"}
    from_env = parse([], env)
    assert from_env.connect == ("tcp/127.0.0.1:1", "tcp/127.0.0.1:2")
    assert (from_env.mode, from_env.mission, from_env.lease_ms) == ("peer", "envmission", 500)
    config = make_zenoh_config(from_env)
    assert json.loads(config.get_json("listen/endpoints")) == ["tcp/127.0.0.1:0"]
    cli = parse(["--mode", "client", "--mission", "m2", "--lease-ms", "2000",
                 "--listen", "tcp/127.0.0.1:9"], env)
    assert (cli.mode, cli.mission, cli.lease_ms, cli.listen) == (
        "client", "m2", 2000, ("tcp/127.0.0.1:9",))


def test_zenoh_config_file_is_the_base(tmp_path: Path) -> None:
    path = tmp_path / "z.json5"
    path.write_text('{ // json5 comment\n queries_default_timeout: 12345, mode: "peer" }')
    settings = parse(["--zenoh-config", str(path)])
    config = make_zenoh_config(settings)
    assert json.loads(config.get_json("queries_default_timeout")) == 12345
    assert json.loads(config.get_json("mode")) == "client"  # options win over the file


@pytest.mark.parametrize("kwargs", [{"mode": "hub"}, {"connect": ("127.0.0.1:7447",)},
                                    {"lease_ms": 10}, {"mission": "a/b"}])
def test_bad_settings_are_one_line_errors(kwargs: dict[str, object]) -> None:
    with pytest.raises(ConfigError):
        ConnectionSettings(**kwargs)  # type: ignore[arg-type]


def test_bad_config_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        make_zenoh_config(ConnectionSettings(zenoh_config=tmp_path / "missing.json5"))
    broken = tmp_path / "broken.json5"
    broken.write_text("{ mode: ")
    with pytest.raises(ConfigError, match="cannot load"):
        make_zenoh_config(ConnectionSettings(zenoh_config=broken))


@pytest.mark.integration
def test_router_port_in_use_fails_clearly(router: str) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "router", "--listen", router],
        capture_output=True, text=True, timeout=20)
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "already in use" in lines[0], result.stderr
    with pytest.raises(RouterError, match="already in use"):
        start_router_process(router)


@pytest.mark.integration
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_router_stops_cleanly_on_signal(free_port: int, signum: int) -> None:
    proc = start_router_process(f"tcp/127.0.0.1:{free_port}")
    proc.send_signal(signum)
    assert proc.wait(timeout=10) == 0
    stop_process(proc)
