"""Mistakes a new user makes with a stopped fleet or no router: one line and a non-zero exit,
quickly, never a traceback or a hang."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from deploy.cli import main
from deploy.fleet import FleetInfo, ProcessRecord, RunDir


def stopped_fleet(tmp_path: Path, processes: tuple[ProcessRecord, ...]) -> Path:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    RunDir(run_dir).write_fleet(FleetInfo(
        mission="gone", endpoint="tcp/127.0.0.1:9", own_router=True, world="open-room",
        algo="opt", robots=2, starts=((0, 0), (2, 2)), time_scale=0.0, created=0.0,
        processes=processes))
    return run_dir


def exited_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.mark.parametrize("with_simhw", [True, False])
def test_kill_hw_on_a_stopped_fleet_is_one_line(tmp_path: Path, with_simhw: bool,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    simhw = (ProcessRecord("simhw", "simhw", exited_pid(), 1, "log"),) if with_simhw else ()
    run_dir = stopped_fleet(tmp_path, simhw)
    started = time.monotonic()
    assert main(["kill", "0", "--hw", "--run-dir", str(run_dir)]) == 2
    assert time.monotonic() - started < 5.0
    err = capsys.readouterr().err
    expected = "is not running (its simhw" if with_simhw else "no router answers at"
    assert expected in err and len(err.splitlines()) == 1, err


def test_monitor_without_a_router_says_so_and_gives_up(free_port: int) -> None:
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "monitor", "--plain", "--exit-when-done",
         "--mission", "nobody", "--connect", f"tcp/127.0.0.1:{free_port}",
         "--duration", "600", "--connect-timeout", "2"],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert time.monotonic() - started < 30
    lines = result.stderr.splitlines()
    assert lines[0].startswith(f"mstc monitor: waiting for a Zenoh router at "
                               f"tcp/127.0.0.1:{free_port}"), result.stderr
    assert lines[-1] == (f"mstc monitor: error: no Zenoh router answered at "
                         f"tcp/127.0.0.1:{free_port} within 2 s (start the fleet with mstc "
                         f"up, or a router with mstc router)")
    assert "Traceback" not in result.stderr


@pytest.mark.integration
def test_monitor_duration_counts_from_the_start(router: str) -> None:
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "monitor", "--plain", "--mission", "quiet",
         "--connect", router, "--duration", "2"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert time.monotonic() - started < 30
    assert result.stdout.splitlines()[-1].split()[1] == "summary"
