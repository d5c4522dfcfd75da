"""``mstc up`` is secure by default: its run directory holds the mission's credentials (mode
0600), its router refuses strangers, and a mission attacked by clients without credentials,
with a wrong password, or with an observer's valid credentials (forged death notices,
heartbeats, statuses, progress, garbage on every key, floods) completes with no robot lost.
Real processes on loopback."""

from __future__ import annotations

import json
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import pick_free_port
from test_fleet_up import RUN_LIMIT, start_up, up_argv, wait_for_fleet

from bus.security import credentials
from deploy.fleet import RunDir

pytestmark = pytest.mark.integration

ATTACKER = Path(__file__).resolve().parent / "attack_client.py"


def attacker(endpoint: str, mission: str, seconds: float,
             *login: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, str(ATTACKER), endpoint, mission, str(seconds),
                             *login], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


@pytest.mark.slow  # over 10 s: CI runs it, the quick loop does not
def test_an_attacked_mission_completes_with_no_robot_lost(tmp_path: Path) -> None:
    port = pick_free_port()
    run_dir = tmp_path / "run"
    up = start_up(port, run_dir, "--time-scale", "40")
    attackers: list[subprocess.Popen[str]] = []
    try:
        info = wait_for_fleet(run_dir, up)
        creds = run_dir / credentials.CREDENTIALS_FILE
        assert stat.S_IMODE(creds.stat().st_mode) == 0o600
        assert info.credentials == str(creds.resolve())
        wrong = tmp_path / "wrong.json"
        credentials.load(creds).rotated().save(wrong)
        endpoint = f"tcp/127.0.0.1:{port}"
        stranger = attacker(endpoint, info.mission, 5)
        impostor = attacker(endpoint, info.mission, 5, "--credentials", str(wrong),
                            "--role", "robot_1")
        observer = attacker(endpoint, info.mission, 8, "--credentials", str(creds),
                            "--role", "observer")
        attackers = [stranger, impostor, observer]
        out, err = up.communicate(timeout=RUN_LIMIT)
        assert up.returncode == 0, out[-3000:] + err[-3000:]
        summary = json.loads((run_dir / "summary.json").read_text())
        assert summary["complete"] is True
        assert summary["robots_lost"] == [], summary
        assert summary["takeovers"] == 0, summary
        assert stranger.communicate(timeout=30)[0].strip() == "refused"
        assert impostor.communicate(timeout=30)[0].strip() == "refused"
        said, why = observer.communicate(timeout=60)
        assert observer.returncode == 0, why[-2000:]
        assert "attacked:" in said, said  # it was connected and did its worst
    finally:
        for proc in (up, *attackers):
            if proc.poll() is None:
                proc.kill()
                proc.communicate()


@pytest.mark.slow
def test_insecure_runs_make_no_credentials(tmp_path: Path) -> None:
    run_dir = tmp_path / "plain"
    done = subprocess.run(up_argv(pick_free_port(), run_dir, "--time-scale", "0",
                                  "--insecure", robots=2), capture_output=True, text=True,
                          timeout=RUN_LIMIT)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert not (run_dir / credentials.CREDENTIALS_FILE).exists()
    assert RunDir(run_dir).read_fleet().credentials is None


def test_up_with_a_credentials_file_of_another_mission_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "c.json"
    credentials.generate("elsewhere", 2).save(path)
    started = time.monotonic()
    done = subprocess.run(up_argv(pick_free_port(), tmp_path / "run", "--credentials",
                                  str(path), robots=2), capture_output=True, text=True,
                          timeout=RUN_LIMIT)
    assert done.returncode == 2 and "mission 'elsewhere'" in done.stderr, done.stderr
    assert time.monotonic() - started < RUN_LIMIT


@pytest.mark.slow  # over 10 s: CI runs it, the quick loop does not
def test_monitor_and_kill_hw_attach_to_a_secure_fleet_with_its_credentials(
        tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    up = start_up(pick_free_port(), run_dir, "--time-scale", "40")
    try:
        info = wait_for_fleet(run_dir, up)
        watch = subprocess.run(
            [sys.executable, "-m", "deploy.cli", "monitor", "--run-dir", str(run_dir),
             "--plain", "--duration", "3"], capture_output=True, text=True, timeout=60)
        assert watch.returncode == 0, watch.stderr[-2000:]
        assert f"watching mission {info.mission}" in watch.stderr
        assert "robot" in watch.stdout, watch.stdout[-2000:]  # it heard the fleet
        kill = subprocess.run(
            [sys.executable, "-m", "deploy.cli", "kill", "1", "--hw", "--run-dir",
             str(run_dir)], capture_output=True, text=True, timeout=60)
        assert kill.returncode == 0, kill.stderr[-2000:]
        out, err = up.communicate(timeout=RUN_LIMIT)
        assert up.returncode == 0, out[-3000:] + err[-3000:]
        summary = json.loads((run_dir / "summary.json").read_text())
        assert summary["complete"] is True
        assert [lost["robot"] for lost in summary["robots_lost"]] == [1], summary
    finally:
        if up.poll() is None:
            up.kill()
            up.communicate()


def test_mstc_credentials_makes_splits_and_rotates(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from deploy.cli import main as cli_main

    path, role = tmp_path / "m.json", tmp_path / "r3.json"
    assert cli_main(["credentials", "new", str(path), "--mission", "m", "--robots", "4"]) == 0
    assert cli_main(["credentials", "new", str(path), "--mission", "m", "--robots", "4"]) == 2
    assert "exists" in capsys.readouterr().err
    creds = credentials.load(path)
    assert cli_main(["credentials", "role", str(path), "robot_3", str(role)]) == 0
    assert credentials.load(role).passwords == {"robot_3": creds.passwords["robot_3"]}
    assert stat.S_IMODE(role.stat().st_mode) == 0o600
    assert cli_main(["credentials", "role", str(path), "robot_9", str(role)]) == 2
    assert cli_main(["credentials", "rotate", str(path)]) == 0
    rotated = credentials.load(path)
    assert rotated.passwords.keys() == creds.passwords.keys() != set()
    assert not set(rotated.passwords.values()) & set(creds.passwords.values())


def test_ros_bridge_on_a_secured_mission_needs_a_ros_router(tmp_path: Path) -> None:
    pytest.importorskip("foxglove_schemas_protobuf")
    path = tmp_path / "c.json"
    credentials.generate("m", 2).save(path)
    done = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "ros-bridge", "--connect",
         f"tcp/127.0.0.1:{pick_free_port()}", "--mission", "m", "--credentials", str(path)],
        capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert "--ros-connect" in done.stderr and "Traceback" not in done.stderr
