"""``mstc agent``'s one command line: every algorithm that runs as a fleet reaches its
family's driver, every family gets the same defaults, ``mstc tree-agent`` is the same command
for the tree family, and option mistakes are one line with exit code 2."""

from __future__ import annotations

import argparse
import dataclasses
import importlib
from types import ModuleType

import pytest

from agent import main
from agent.core.config import AgentConfig, config_from_args
from agent.tree import command as tree_agent
from planner.algorithms import Family, algorithm, names

FAMILY_ARGS = {Family.OFFLINE: ["--world", "example"], Family.ONLINE: [],
               Family.TREE: ["--tree", "perfect:N=2,H=2"]}


def parse(module: ModuleType, command: str, argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=f"mstc {command}")
    module.add_arguments(parser)
    args = parser.parse_args(argv)
    args.command = command
    return args


@pytest.mark.parametrize("name", names(fleet=True))
def test_every_fleet_algorithm_reaches_its_family_driver(name: str) -> None:
    family = algorithm(name).family
    assert name in main.agent_algorithms()
    args = parse(main, "agent", ["--id", "1", "--robots", "2", "--algo", name,
                                 *FAMILY_ARGS[family]])
    options = main.OPTIONS[family].from_args(args)
    assert dataclasses.is_dataclass(options)
    assert callable(importlib.import_module(main.DRIVERS[family]).drive)


def test_plan_only_algorithms_are_not_offered() -> None:
    offered = set(main.agent_algorithms())
    assert offered == set(names(fleet=True))
    assert not offered & set(names(fleet=False))
    assert set(main.agent_algorithms(Family.TREE)) == set(names(Family.TREE, fleet=True))


@pytest.mark.parametrize("module, command, argv", [
    (main, "agent", ["--algo", "nb", "--world", "example"]),
    (main, "agent", ["--algo", "ormstc"]),
    (main, "agent", ["--algo", "cocta", "--tree", "office"]),
    (tree_agent, "tree-agent", ["--tree", "office"]),
])
def test_every_family_and_spelling_gets_one_set_of_defaults(
        module: ModuleType, command: str, argv: list[str]) -> None:
    config = config_from_args(parse(module, command, ["--id", "0", "--robots", "2", *argv]))
    assert dataclasses.replace(config, algo="x") == AgentConfig(robot=0, k=2, algo="x")


def test_tree_agent_is_mstc_agent_with_a_tree_algo() -> None:
    argv = ["--id", "1", "--robots", "3", "--tree", "office", "--step-timeout", "3",
            "--settle", "0.5", "--dead-after", "2"]
    old = parse(tree_agent, "tree-agent", [*argv, "--algo", "ncocta"])
    new = parse(main, "agent", [*argv, "--algo", "ncocta"])
    assert config_from_args(old) == config_from_args(new)
    assert main.OPTIONS[Family.TREE].from_args(old) == main.OPTIONS[Family.TREE].from_args(new)
    assert parse(tree_agent, "tree-agent", argv).algo == "cocta"


@pytest.mark.parametrize("module, command, argv, message", [
    (main, "agent", ["--algo", "nb"], "--algo nb needs --world"),
    (main, "agent", ["--algo", "cocta"], "--algo cocta needs --tree SPEC"),
    (main, "agent", ["--algo", "bt", "--world", "example", "--tree", "office"],
     "invalid choice for --algo bt: 'office'"),
    (main, "agent", ["--algo", "ormstc", "--id", "2"], "--id 2 is not below --robots 2"),
    (tree_agent, "tree-agent", ["--tree", "office", "--id", "5"],
     "--id 5 is not below --robots 2"),
])
def test_option_mistakes_are_one_line_and_exit_2(
        module: ModuleType, command: str, argv: list[str], message: str,
        capsys: pytest.CaptureFixture[str]) -> None:
    args = parse(module, command, ["--id", "0", "--robots", "2", *argv])
    assert main.run(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"mstc {command}: error: ")
    assert message in err
