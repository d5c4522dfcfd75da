"""Smoke runs of the paper reproductions on tiny settings: the command runs, writes its CSV and
PNG, and the rows obey what the papers prove (opt <= bt <= nb; ORMSTC leaves nothing
uncovered, even with robots killed)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from deploy.cli import main

PNG = b"\x89PNG\r\n\x1a\n"


def rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_repro_mstc_rows_keep_opt_below_bt_below_nb(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["repro-mstc", "--trials", "2", "--robots", "2,4", "--out", str(tmp_path)]) == 0
    table = rows(tmp_path / "mstc003.csv")
    assert {int(r["k"]) for r in table} == {2, 4} and {r["obstacles"] for r in table} >= {"0"}
    for r in table:
        assert int(r["opt"]) <= int(r["bt"]) <= int(r["nb"])
        assert int(r["nb"]) <= int(r["n"]) - int(r["k"])  # paper 003, Theorem 5 (in moves)
    assert (tmp_path / "mstc003.png").read_bytes()[:8] == PNG
    assert "faster" in capsys.readouterr().out


def test_repro_ormstc_covers_everything_with_kills(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["repro-ormstc", "--trials", "1", "--robots", "2,3", "--out",
                 str(tmp_path)]) == 0
    table = rows(tmp_path / "ormstc_fig4.csv")
    assert {r["scenario"] for r in table} == {"none", "one", "k-1"}
    assert all(int(r["missed"]) == 0 for r in table)
    # without failures the only revisits are each robot closing its cycle at its start
    assert all(int(r["revisits"]) <= int(r["k"]) for r in table if r["scenario"] == "none")
    assert (tmp_path / "ormstc_fig4.png").read_bytes()[:8] == PNG
    assert "0 reachable sub-cells left uncovered" in capsys.readouterr().out


def test_repro_createtree_gains_are_consistent(tmp_path: Path) -> None:
    assert main(["repro-createtree", "--inputs", "2", "--robots", "3,5", "--obstacles", "0,40",
                 "--part", "main", "--out", str(tmp_path), "--img", str(tmp_path)]) == 0
    table = rows(tmp_path / "createtree_random_vs_create.csv")
    assert len(table) == 4
    for r in table:
        nb_random, nb_create = float(r["nb_random"]), float(r["nb_create"])
        assert float(r["nb_gain"]) == pytest.approx(1 - nb_create / nb_random)
        assert float(r["opt_create"]) <= nb_create  # opt never worse than NB on one tree
    assert (tmp_path / "createtree_improvement.png").read_bytes()[:8] == PNG
