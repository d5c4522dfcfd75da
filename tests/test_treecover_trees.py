"""Tree environments: perfect, general (cut) and file trees, and their parse errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.errors import PlannerError, TreeFormatError
from planner.treecover.trees import (
    general_tree,
    load_tree,
    office_tree,
    parse_tree,
    perfect_tree,
    tree_from_spec,
)


def _check_tree(tree) -> None:  # type: ignore[no-untyped-def]
    assert tree.parent[0] == -1
    assert np.all(tree.parent[1:] < np.arange(1, tree.n))
    for v in range(tree.n):
        for u in tree.children(v):
            assert tree.parent[u] == v
            assert tree.depth[u] == tree.depth[v] + 1
    assert sum(len(tree.children(v)) for v in range(tree.n)) == tree.n - 1


@pytest.mark.parametrize(("n", "h"), [(2, 0), (2, 3), (3, 2), (4, 2), (1, 4)])
def test_perfect_tree_shape(n: int, h: int) -> None:
    tree = perfect_tree(n, h)
    _check_tree(tree)
    assert tree.n == sum(n ** i for i in range(h + 1))
    assert tree.height == h
    internal = [v for v in range(tree.n) if tree.depth[v] < h]
    assert all(len(tree.children(v)) == n for v in internal)


def test_general_tree_removes_whole_subtrees() -> None:
    full = perfect_tree(2, 6)
    cut = general_tree(2, 6, remove=3, at_height=2, seed=7)
    _check_tree(cut)
    assert cut.n == full.n - 3 * 7  # each removed height-2 node takes 7 nodes with it
    assert general_tree(2, 6, 3, 2, 7).parent.tolist() == cut.parent.tolist()


def test_general_tree_rejects_impossible_cuts() -> None:
    with pytest.raises(PlannerError, match="remove"):
        general_tree(2, 4, remove=2, at_height=3, seed=0)  # only 2 nodes there


def test_office_tree_loads() -> None:
    tree = office_tree()
    _check_tree(tree)
    assert tree.label(0) == "lobby"
    assert tree.n == 33


def test_file_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "t.tree"
    path.write_text("# comment\nroot a  # trailing\nroot b\n\na c\n")
    tree = load_tree(path)
    assert [tree.label(v) for v in range(tree.n)] == ["root", "a", "b", "c"]
    assert tree_from_spec(str(path)).n == 4


@pytest.mark.parametrize(("text", "line", "what"), [
    ("a b\nb\n", 2, "expected 'parent child'"),
    ("a b\nc b\n", 2, "already has a parent"),
    ("a b\nc d\n", None, "expected one root"),
    ("a a\n", 1, "its own parent"),
    ("# nothing\n", None, "at least one"),
    ("r a\nb c\nc b\n", None, "one root|not reachable|cycle"),
])
def test_parse_errors_name_file_and_line(text: str, line: int | None, what: str) -> None:
    with pytest.raises(TreeFormatError, match=what) as info:
        parse_tree(text, "x.tree")
    assert str(info.value).startswith("x.tree")
    if line is not None:
        assert info.value.line == line


@pytest.mark.parametrize("spec", ["perfect:N=2", "perfect:N=2,H=x", "general:N=2,H=3,bad=1",
                                  "no/such/file.tree"])
def test_bad_specs_are_planner_errors(spec: str) -> None:
    with pytest.raises(PlannerError):
        tree_from_spec(spec)


def test_specs() -> None:
    assert tree_from_spec("perfect:N=3,H=2").n == 13
    assert tree_from_spec("general:N=2,H=5,remove=2,at=1,seed=3").n == 63 - 6
