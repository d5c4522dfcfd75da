"""The algorithm registry is the one source of names: every command that takes ``--algo``
offers exactly the registered algorithms it should, and every registered algorithm has a
lockstep run (and a fleet run where it declares one)."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from planner.algorithms import ALGORITHMS, Family, algorithm, names
from planner.errors import UnknownAlgorithmError
from planner.geometry import cell_of
from planner.grid import work_area
from planner.maps import resolve_world
from planner.offline.machine import Finished
from planner.placement import random_starts
from planner.treecover.trees import tree_from_spec
from planner.trees import build_tree

MAIN = "import sys; from deploy.cli import main; sys.exit(main())"


def algo_choices(command: str) -> tuple[str, ...]:
    """The ``--algo`` choices of ``mstc COMMAND``, read from its real parser."""
    from deploy.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    action = next(a for a in sub.choices[command]._actions if "--algo" in a.option_strings)
    assert action.choices is not None
    return tuple(action.choices)


@pytest.mark.parametrize(("command", "expected"), [
    ("plan", names(plans=True)),
    ("up", tuple(n for n in names(fleet=True) if ALGORITHMS[n].family is not Family.TREE)),
    ("agent", names(fleet=True)),
    ("tree-cover", names(Family.TREE)),
    ("tree-fleet", names(Family.TREE, fleet=True)),
])
def test_each_command_offers_the_registered_algorithms(command: str,
                                                       expected: tuple[str, ...]) -> None:
    assert algo_choices(command) == expected


def test_an_unknown_name_is_a_user_error_naming_the_choices() -> None:
    with pytest.raises(UnknownAlgorithmError, match="choose one of nb, bt, opt"):
        algorithm("dijkstra")


@pytest.mark.parametrize("name", names(Family.OFFLINE))
def test_every_offline_algorithm_plans_and_replays_with_a_death(name: str) -> None:
    entry = algorithm(name)
    grid = resolve_world("office")
    starts = random_starts(grid, 4, 3)
    area = work_area(grid, starts)
    tree = build_tree(area.cells, "dfs", seed=3, starts=[cell_of(s) for s in starts])
    plan = entry.load_plan()(area, tree, name, 3)
    assert plan.algo.startswith(name) or name == "balanced"
    assert [rp.start for rp in plan.robots] == list(starts)
    result = entry.load_lockstep()(plan, {plan.robots[1].robot: 5}, detection_delay=1)
    assert result.complete and int(result.covered.sum()) == area.n
    machine = entry.load_machine()(plan, plan.robots[0].robot)  # the agent's state machine
    assert not isinstance(machine.next_action(), Finished)


def test_the_online_algorithm_covers_in_lockstep() -> None:
    entry = algorithm("ormstc")
    grid = resolve_world("example")
    result = entry.load_lockstep()(grid, [(0, 0), (8, 10)])
    assert result.finished and int(result.covered.sum()) == int(grid.free.sum())


@pytest.mark.parametrize("name", names(Family.TREE))
def test_every_tree_algorithm_covers_in_lockstep(name: str) -> None:
    tree = tree_from_spec("perfect:N=2,H=4")
    result = algorithm(name).load_lockstep()(tree, 4, name)
    assert (result.visit_time >= 0).all()


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.parametrize("name", names(fleet=True))
def test_every_fleet_algorithm_completes_as_processes(name: str, free_port: int,
                                                      tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    common = ["--plain", "--listen", f"tcp/127.0.0.1:{free_port}", "--run-dir", str(run_dir)]
    if ALGORITHMS[name].family is Family.TREE:
        argv = ["tree-fleet", "--tree", "perfect:N=2,H=3", "--robots", "3", "--algo", name]
    else:
        # A small world: the subject is that every algorithm runs as a fleet, not the walk
        # (ORMSTC took 25 s on open-room).
        world = tmp_path / "small.txt"
        world.write_text("\n".join(["................"] * 5 + ["......####......"] * 2
                                   + ["................"] * 5) + "\n")
        argv = ["up", "-n", "3", "--world", str(world), "--algo", name, "--time-scale", "0",
                "--lease-ms", "5000", "--dead-after", "5", "--stall-timeout", "30"]
    done = subprocess.run([sys.executable, "-c", MAIN, *argv, *common], capture_output=True,
                          text=True, timeout=180)
    assert done.returncode == 0, done.stdout + done.stderr
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["complete"] is True
