"""``mstc up --record``: the launcher's whole mission recorded, and its report."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import pick_free_port

pytestmark = [pytest.mark.integration, pytest.mark.slow]

ROOM = ["............"] * 5 + ["....##......"] * 2 + ["............"] * 5


def up_and_report(tmp_path: Path, rows: list[str], starts: str, algo: str
                  ) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run `mstc up --record` on ``rows``, then `mstc report --json` on the recording: both
    must succeed; the report's JSON and the launcher's summary.json."""
    world = tmp_path / "room.txt"
    world.write_text("\n".join(rows) + "\n")
    record = tmp_path / "up.jsonl"
    up = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "up", "-n", "3", "--world", str(world),
         "--starts", starts, "--algo", algo, "--time-scale", "0", "--plain",
         "--listen", f"tcp/127.0.0.1:{pick_free_port()}", "--run-dir", str(tmp_path / "run"),
         "--record", str(record)], capture_output=True, text=True, timeout=240)
    assert up.returncode == 0, up.stdout + up.stderr
    report = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "report", str(record), "--json"],
        capture_output=True, text=True, timeout=60)
    assert report.returncode == 0, report.stdout + report.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    return json.loads(report.stdout), summary


def test_up_records_a_mission_the_report_verifies(tmp_path: Path) -> None:
    data, summary = up_and_report(tmp_path, ROOM, "0,0;4,8;10,2", "nb")
    assert data["coverage_percent"] == 100.0 and data["ok"]
    # The recording alone gives the launcher's own figures.
    assert data["covered"] == summary["covered"] == summary["reachable"]
    assert max(r["moves"] for r in data["robots"]) == summary["makespan_moves"]
    assert sum(r["moves"] for r in data["robots"]) == summary["total_moves"]
    # one definition of the figures (deploy.monitor.figures) for the summary and the report
    assert data["coverage_moves"] == summary["makespan_moves"]
    assert data["coverage_sim_seconds"] == summary["sim_seconds"]
    assert data["revisits"] == summary["revisited"]


# 4 x 6 cells with a one-cell pillar (ORMSTC obstacles fill whole cells, docs/ormstc.md).
ORMSTC_ROOM = ["............"] * 2 + ["......##...."] * 2 + ["............"] * 4


def test_up_records_an_ormstc_mission_the_report_passes(tmp_path: Path) -> None:
    """A clean ORMSTC run passes the redundancy check: every revisit simhw counted is a
    look step the agents announced or a start's closing re-entry."""
    data, summary = up_and_report(tmp_path, ORMSTC_ROOM, "0,0;0,11;7,5", "ormstc")
    assert data["coverage_percent"] == 100.0 and data["ok"]
    checks = {i["name"]: i["status"] for i in data["invariants"]}
    assert checks["no sub-cell covered twice by coverage moves (ormstc)"] == "ok"
    # simhw's own count of entries beyond the first, split by the report
    revisits = summary["total_moves"] + len(data["robots"]) - summary["covered"]
    assert data["revisits"] == revisits
    assert data["coverage_revisits"] == 0 and data["closing_reentries"] == 3
    assert data["look_steps"] + data["closing_reentries"] == revisits
    # the agents' own counts of their look steps, from their completion events
    looks = {}
    for line in (tmp_path / "up.jsonl").read_text().splitlines()[1:]:
        entry = json.loads(line)
        if entry["kind"] == "event" and entry["msg"]["kind"] == "completed":
            found = re.search(r"(\d+) steps to look", entry["msg"]["detail"])
            assert found is not None
            looks[entry["msg"]["robot"]] = int(found.group(1))
    assert sorted(looks) == [0, 1, 2]
    assert [r["look_steps"] for r in data["robots"]] == [looks[r] for r in range(3)]
