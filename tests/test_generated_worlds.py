"""Generated worlds (planner.maps.generated): a spec string names the same map everywhere."""

from __future__ import annotations

import json

import numpy as np
import pytest

from deploy.cli import main
from planner.errors import MapReadError
from planner.grid import label_components
from planner.maps import resolve_world
from planner.maps.generated import EXAMPLES, KINDS, generated_world, is_generated
from planner.maps.rooms import rooms_cells


def cells_of(spec: str) -> np.ndarray:
    free = resolve_world(spec).free
    # generated worlds are whole cells: each 2 x 2 block all free or all blocked
    blocks = free.reshape(free.shape[0] // 2, 2, free.shape[1] // 2, 2)
    assert (blocks.all(axis=(1, 3)) == blocks.any(axis=(1, 3))).all()
    return np.asarray(blocks.all(axis=(1, 3)))


@pytest.mark.parametrize("spec", EXAMPLES)
def test_a_spec_names_one_connected_map_of_its_size(spec: str) -> None:
    cells = cells_of(spec)
    rows, cols = (int(x) for x in spec.split(":")[1].split("x"))
    assert cells.shape == (rows, cols)
    assert cells.any() and label_components(cells)[1] == 1
    assert (cells_of(spec) == cells).all(), "the same spec, the same map"
    assert resolve_world(spec).name == spec
    if spec.split(":")[0] != "open":  # seeded kinds: another seed, another map
        other = spec.rsplit(":", 1)[0] + ":" + str(int(spec.rsplit(":", 1)[1]) + 1)
        assert (cells_of(other) != cells).any()


def test_every_kind_has_an_example() -> None:
    assert sorted({spec.split(":")[0] for spec in EXAMPLES}) == sorted(KINDS)


@pytest.mark.parametrize(("spec", "blocked"), [
    ("obstacles:20x30:80:3", 80), ("obstacles:40x40:30%:1", 480), ("obstacles:8x8:0:1", 0)])
def test_obstacles_block_exactly_the_cells_asked(spec: str, blocked: int) -> None:
    cells = cells_of(spec)
    assert int((~cells).sum()) == blocked


@pytest.mark.parametrize("seed", range(4))
def test_a_maze_is_a_tree_of_one_cell_corridors(seed: int) -> None:
    cells = cells_of(f"maze:11x15:{seed}")
    junctions = 6 * 8  # the cells at even rows and columns
    assert cells[::2, ::2].all()
    assert not cells[1::2, 1::2].any()  # wall posts
    # a perfect maze: the junctions joined by exactly junctions - 1 corridor cells
    assert int(cells.sum()) == junctions + junctions - 1
    assert label_components(cells)[1] == 1


@pytest.mark.parametrize("seed", range(6))
def test_rooms_are_joined_by_doors_in_one_cell_walls(seed: int) -> None:
    rows, cols = 31, 43
    cells = rooms_cells(rows, cols, np.random.default_rng(seed))
    assert label_components(cells)[1] == 1
    full_rows = [r for r in range(rows) if cells[r].sum() > cols / 2]
    walls = [r for r in range(rows) if cells[r].sum() <= cols / 2]
    assert walls, "a plan this size has walls"
    for r in walls:  # a wall is mostly blocked, and has at least one door
        assert 0 < cells[r].sum() < cols / 2
        assert r - 1 in full_rows and r + 1 in full_rows, "walls are one cell thick"


@pytest.mark.parametrize(("spec", "problem"), [
    ("rooms:30x40", "rooms takes 2 field(s)"),
    ("maze:14x23:1", "a maze has odd sides"),
    ("obstacles:10x10:100%:1", "leaves no free cell"),
    ("obstacles:10x10:100:1", "leave no free cell"),
    ("city:0x5:1", "sides must be"),
    ("open:20x30x2", "is not ROWSxCOLS"),
    ("rooms:30x40:abc", "seed 'abc' is not a whole number"),
    ("obstacles:3x3:8:1", "could not place 8 obstacles"),
])
def test_a_malformed_spec_says_what_is_wrong(spec: str, problem: str) -> None:
    assert is_generated(spec)
    with pytest.raises(MapReadError) as caught:
        resolve_world(spec)
    assert problem in str(caught.value) and "rooms:30x40:3" in str(caught.value)


def test_names_that_are_no_spec_are_left_to_files_and_builtin_worlds() -> None:
    assert not is_generated("office") and not is_generated("tunnel:3x3:1")
    assert not is_generated("maps/floor.yaml")
    with pytest.raises(MapReadError, match="unknown kind"):
        generated_world("tunnel:3x3:1")


def test_mstc_plan_takes_a_generated_world(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--map", "rooms:16x20:2", "--random-robots", "4", "--seed", "1",
                 "--algo", "balanced", "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    covered = {tuple(sub) for robot in plan["robots"] for sub in robot["path"]}
    assert len(covered) == int(cells_of("rooms:16x20:2").sum()) * 4
