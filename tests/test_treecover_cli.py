"""``mstc tree-cover`` and ``mstc repro-cocta`` end to end (in process)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from deploy.cli import main


def test_tree_cover_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree-cover", "--tree", "perfect:N=3,H=4", "--robots", "10", "--algo",
                 "ncocta", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["connected_every_step"] is True
    assert summary["nodes"] == 121
    assert summary["single_robot_time"] == 240
    assert summary["speedup"] == pytest.approx(240 / summary["coverage_time"], abs=1e-3)


def test_tree_cover_plot_and_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tree = tmp_path / "t.tree"
    tree.write_text("r a\nr b\na c\na d\nb e\n")
    png = tmp_path / "run.png"
    assert main(["tree-cover", "--tree", str(tree), "--robots", "3", "--plot", str(png)]) == 0
    assert png.stat().st_size > 0
    assert "coverage_time" in capsys.readouterr().out


@pytest.mark.parametrize("args", [["--tree", "perfect:N=3"], ["--tree", "missing.tree"],
                                  ["--tree", "perfect:N=2,H=3", "--robots", "0"]])
def test_user_mistakes_are_one_line(args: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["tree-cover", *args]
    if "--robots" not in args:
        argv += ["--robots", "3"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.slow
def test_repro_quick_writes_csv_and_png(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    assert main(["repro-cocta", "--quick", "--out", str(tmp_path)]) == 0
    for name in ("cocta_example.csv", "cocta_perfect.csv", "cocta_heights.csv",
                 "cocta_general.csv", "cocta_fig4.png", "cocta_general.png"):
        assert (tmp_path / name).stat().st_size > 0
