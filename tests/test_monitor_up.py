"""``mstc up --record``: the launcher's whole mission recorded, and its report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import pick_free_port

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOM = ["............"] * 5 + ["....##......"] * 2 + ["............"] * 5


def test_up_records_a_mission_the_report_verifies(tmp_path: Path) -> None:
    world = tmp_path / "room.txt"
    world.write_text("\n".join(ROOM) + "\n")
    record = tmp_path / "up.jsonl"
    up = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "up", "-n", "3", "--world", str(world),
         "--starts", "0,0;4,8;10,2", "--algo", "nb", "--time-scale", "0", "--plain",
         "--listen", f"tcp/127.0.0.1:{pick_free_port()}", "--run-dir", str(tmp_path / "run"),
         "--record", str(record)], capture_output=True, text=True, timeout=240)
    assert up.returncode == 0, up.stdout + up.stderr
    report = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "report", str(record), "--json"],
        capture_output=True, text=True, timeout=60)
    assert report.returncode == 0, report.stdout + report.stderr
    data = json.loads(report.stdout)
    assert data["coverage_percent"] == 100.0 and data["ok"]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    # The recording alone gives the launcher's own figures.
    assert data["covered"] == summary["covered"] == summary["reachable"]
    assert max(r["moves"] for r in data["robots"]) == summary["makespan_moves"]
    assert sum(r["moves"] for r in data["robots"]) == summary["total_moves"]
