"""``--plot`` and ``--png``: a bad figure path is one line naming the option, found before
any work; a path without a suffix gets ``.png`` and the message names the file written."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_monitor_fixtures import M, open_room, run_mission, two_robot_walks

from bus.messages import SCHEMA_VERSION
from deploy.cli import main
from deploy.monitor.recorder import RecordWriter
from deploy.monitor.types import Header

PLAN = ["plan", "--world", "open-room", "-n", "2", "--plot"]
TREE = ["tree-cover", "--tree", "office", "--robots", "3", "--plot"]


def recording(tmp_path: Path) -> Path:
    path = tmp_path / "rec.jsonl"
    with RecordWriter(path, Header(M, 0.0, "monitor", SCHEMA_VERSION)) as writer:
        for record in run_mission(open_room(), two_robot_walks()).records:
            writer.write(record)
    return path


@pytest.mark.parametrize("bad", ["x.foo", "missing/dir/p.png"])
def test_bad_figure_paths_are_one_line(tmp_path: Path, bad: str,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    target = str(tmp_path / bad)
    why = "cannot draw a .foo file" if bad.endswith(".foo") else "does not exist"
    for argv in ([*PLAN, target], [*TREE, target],
                 ["report", str(recording(tmp_path)), "--png", target]):
        assert main(argv) == 2
        out, err = capsys.readouterr()
        option = "--png" if argv[0] == "report" else "--plot"
        assert err.startswith(f"mstc {argv[0]}: error: {option} {target}: ") and why in err
        assert len(err.splitlines()) == 1 and not out, err


def test_a_path_without_suffix_gets_png_and_says_so(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*PLAN, str(tmp_path / "out")]) == 0
    assert f"plot written to {tmp_path / 'out.png'}" in capsys.readouterr().out
    assert (tmp_path / "out.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["report", str(recording(tmp_path)), "--png", str(tmp_path / "r")]) == 0
    assert (tmp_path / "r.png").read_bytes()[:4] == b"\x89PNG"


def test_an_unwritable_figure_is_one_line(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "taken.png").mkdir()  # a directory where the file should go
    assert main([*PLAN, str(tmp_path / "taken.png")]) == 2
    err = capsys.readouterr().err
    assert "--plot" in err and "cannot write" in err and len(err.splitlines()) == 1, err
