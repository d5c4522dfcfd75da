"""`mstc plan` end to end: JSON shape, readable errors, plot output."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from deploy.cli import main
from planner.experiments.instances import based_sub_cells, grid_with_obstacles
from planner.grid import label_components, work_area
from planner.maps import resolve_world
from planner.metrics import lower_bound


def run_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(["plan", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("algo", ["nb", "bt", "opt"])
def test_plan_json_covers_the_work_area(capsys: pytest.CaptureFixture[str], algo: str) -> None:
    plan = run_json(capsys, "--map", "office", "--random-robots", "4", "--seed", "3",
                    "--algo", algo, "--tree", "kruskal")
    grid = resolve_world("office")
    starts = [tuple(r["start"]) for r in plan["robots"]]
    area = work_area(grid, starts)
    assert plan["n"] == area.n and plan["k"] == 4
    visited: dict[tuple[int, int], set[int]] = {}
    for robot, r in enumerate(plan["robots"]):
        path = [tuple(p) for p in r["path"]]
        assert path[0] == tuple(r["start"])
        assert r["steps"] == len(path) - 1
        for (r1, c1), (r2, c2) in itertools.pairwise(path):
            assert abs(r1 - r2) + abs(c1 - c2) == 1
        for p in path:
            visited.setdefault(p, set()).add(robot)
    assert set(visited) == {tuple(map(int, p)) for p in np.argwhere(area.sub_cells)}
    assert all(len(who) == 1 for who in visited.values())
    assert plan["makespan"] == max(r["steps"] for r in plan["robots"])
    assert plan["makespan"] >= lower_bound(plan["n"], plan["k"]) == plan["lower_bound"]


def test_opt_never_worse_than_nb_from_the_cli(capsys: pytest.CaptureFixture[str]) -> None:
    spans = {algo: run_json(capsys, "--map", "example", "--random-robots", "5", "--seed", "9",
                            "--algo", algo)["makespan"] for algo in ("nb", "bt", "opt")}
    assert spans["opt"] <= spans["bt"] <= spans["nb"]


def test_speeds_shift_work_to_the_fast_robot(capsys: pytest.CaptureFixture[str]) -> None:
    plan = run_json(capsys, "--map", "open-room", "--starts", "0,0;10,10", "--algo", "opt",
                    "--speeds", "1,3")
    slow, fast = plan["robots"]
    assert fast["steps"] > slow["steps"]
    assert plan["makespan_time"] == pytest.approx(
        max(slow["steps"] / 1, fast["steps"] / 3))


@pytest.mark.parametrize(("argv", "needle"), [
    (["--map", "nowhere", "--starts", "0,0"], "builtin worlds"),
    (["--map", "example", "--starts", "0,0;0,0"], "both start at (0, 0)"),
    (["--map", "example", "--starts", "0;1"], "expected 'row,col'"),
    (["--map", "example", "--starts", "999,0"], "outside"),
    (["--map", "example", "--starts", "0,0", "--algo", "nb", "--speeds", "2"], "--algo opt"),
    (["--map", "example", "--starts", "0,0;0,2", "--fuel", "3,3"], "fuel"),
])
def test_user_mistakes_are_one_line(capsys: pytest.CaptureFixture[str], argv: list[str],
                                    needle: str) -> None:
    assert main(["plan", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("mstc plan: error:") and "\n" not in err
    assert needle in err


@pytest.mark.parametrize(("argv", "needle"), [
    (["up", "-n", "0"], "expected an integer >= 1, got '0'"),
    (["up", "--algo", "foo"], "invalid choice: 'foo'"),
    (["plan", "--map"], "expected one argument"),
    # numpy refuses a negative seed with a traceback: every --seed is checked first
    *[([command, "--seed", "-1"], "argument --seed: expected an integer >= 0, got '-1'")
      for command in ("up", "plan", "chaos", "simhw", "agent", "repro-mstc", "repro-tmstc",
                      "repro-ormstc", "repro-createtree")],
])
def test_argument_errors_are_one_line_without_the_usage_block(
        capsys: pytest.CaptureFixture[str], argv: list[str], needle: str) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"mstc {argv[0]}: error:") and "\n" not in err
    assert needle in err and f"mstc {argv[0]} --help" in err


def test_plot_writes_a_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import matplotlib.image

    out = tmp_path / "plan.png"
    assert main(["plan", "--map", "example", "--random-robots", "3", "--plot", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "makespan" in capsys.readouterr().out
    pixels = matplotlib.image.imread(out)
    assert pixels.shape[0] >= 200 and pixels.shape[1] >= 200
    colours = np.unique(pixels[..., :3].reshape(-1, 3).round(2), axis=0)
    assert len(colours) >= 4  # background, obstacles and at least two robots' paths


def test_obstacle_grids_stay_connected_with_the_requested_count() -> None:
    for seed in range(5):
        cells = grid_with_obstacles(20, 30, 80, np.random.default_rng(seed))
        assert int((~cells).sum()) == 80
        assert label_components(cells)[1] == 1


def test_based_starts_are_distinct_and_free() -> None:
    cells = grid_with_obstacles(10, 12, 10, np.random.default_rng(1))
    starts = based_sub_cells(cells, 9, 2, np.random.default_rng(2))
    assert len(set(starts)) == 9
    fine = np.repeat(np.repeat(cells, 2, 0), 2, 1)
    assert all(fine[r, c] for r, c in starts)


@pytest.mark.parametrize("tree", ["createtree", "tmstc"])
def test_paper_trees_plan_the_whole_area(capsys: pytest.CaptureFixture[str], tree: str) -> None:
    plan = run_json(capsys, "--map", "office", "--random-robots", "5", "--seed", "4",
                    "--algo", "opt", "--tree", tree)
    starts = [tuple(r["start"]) for r in plan["robots"]]
    area = work_area(resolve_world("office"), starts)
    covered = {tuple(p) for r in plan["robots"] for p in r["path"]}
    assert covered == {tuple(map(int, p)) for p in np.argwhere(area.sub_cells)}


def test_balanced_plan_reaches_the_bound_on_an_open_grid(
        capsys: pytest.CaptureFixture[str]) -> None:
    plan = run_json(capsys, "--map", "grid30x20", "--random-robots", "10", "--seed", "1",
                    "--algo", "balanced")
    starts = [tuple(r["start"]) for r in plan["robots"]]
    area = work_area(resolve_world("grid30x20"), starts)
    covered = {tuple(p) for r in plan["robots"] for p in r["path"]}
    assert covered == {tuple(map(int, p)) for p in np.argwhere(area.sub_cells)}
    assert plan["makespan"] <= plan["lower_bound"] + 2


def test_plan_spellings_world_map_robots_starts_agree(capsys: pytest.CaptureFixture[str]) -> None:
    """--world and --map name one option; --robots K (and -n K, and the old --random-robots K)
    is a count; start positions are --starts, and the old --robots 'R,C;...' still works with
    a deprecation warning."""
    base = run_json(capsys, "--map", "example", "--random-robots", "3", "--seed", "5")
    for spelling in (["--world", "example", "--robots", "3"], ["--map", "example", "-n", "3"]):
        assert run_json(capsys, *spelling, "--seed", "5") == base
    starts = ";".join(f"{r['start'][0]},{r['start'][1]}" for r in base["robots"])
    assert run_json(capsys, "--world", "example", "--starts", starts, "--seed", "5") == base
    assert main(["plan", "--world", "example", "--robots", starts, "--seed", "5",
                 "--json"]) == 0
    done = capsys.readouterr()
    assert json.loads(done.out) == base
    assert "deprecated, use --starts" in done.err
    assert main(["plan", "--world", "example", "--robots", "0"]) == 2
    assert "at least 1 robot" in capsys.readouterr().err


def test_a_large_maps_balanced_plan_says_on_stderr_that_it_plans(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """20 robots on rooms:120x120:1 planned for 25 s with nothing printed; the JSON on
    stdout stays one document."""
    from deploy import settings

    argv = ["plan", "--map", "office", "--random-robots", "3", "--algo", "balanced", "--json"]
    assert main(argv) == 0
    assert capsys.readouterr().err == ""  # 884 sub-cells: not worth a word
    monkeypatch.setattr(settings, "LARGE_MAP_SUB_CELLS", 100)  # the office counts as large
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["k"] == 3
    assert err == "planning balanced for 3 robots on 884 sub-cells...\n"
