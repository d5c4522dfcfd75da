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
