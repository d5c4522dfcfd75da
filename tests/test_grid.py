"""Grid model: coarse cells, components (against scipy's connected_components), work-area errors."""

from __future__ import annotations

import numpy as np
import pytest
from balanced_helpers import grid_distances
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planner.errors import (
    DisconnectedRobotsError,
    EmptyMapError,
    RobotPlacementError,
)
from planner.grid import FAR, breadth_first, coarsen, label_components, label_linked, work_area
from planner.maps import parse_ascii
from planner.types import OccupancyGrid


def grid_links(free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every edge between two 4-adjacent free cells, as right/down masks."""
    right = np.zeros(free.shape, dtype=bool)
    down = np.zeros(free.shape, dtype=bool)
    right[:, :-1] = free[:, :-1] & free[:, 1:]
    down[:-1, :] = free[:-1, :] & free[1:, :]
    return right, down


def oracle_labels(cells: np.ndarray, right: np.ndarray,
                  down: np.ndarray) -> tuple[np.ndarray, int]:
    """scipy's connected_components over the linked cells, renumbered 1.. in raster order."""
    h, w = cells.shape
    flat = np.arange(h * w).reshape(h, w)
    across = right[:, :-1] & cells[:, :-1] & cells[:, 1:]
    below = down[:-1, :] & cells[:-1, :] & cells[1:, :]
    u = np.concatenate([flat[:, :-1][across], flat[:-1, :][below]])
    v = np.concatenate([flat[:, 1:][across], flat[1:, :][below]])
    graph = coo_matrix((np.ones(u.size), (u, v)), shape=(h * w, h * w))
    _, component = connected_components(graph, directed=False)
    labels = np.zeros(h * w, dtype=np.int64)
    renumber: dict[int, int] = {}
    for i in np.flatnonzero(cells.ravel()).tolist():
        labels[i] = renumber.setdefault(int(component[i]), len(renumber) + 1)
    return labels.reshape(h, w), len(renumber)


def assert_matches_oracle(free: np.ndarray) -> None:
    labels, count = label_components(free)
    oracle, oracle_count = oracle_labels(free, *grid_links(free))
    assert count == oracle_count
    assert np.array_equal(labels, oracle)


@st.composite
def corridor_grids(draw: st.DrawFn) -> np.ndarray:
    """Blocked grids crossed by random one-cell-wide corridors (long thin components)."""
    h = draw(st.integers(1, 24))
    w = draw(st.integers(1, 24))
    free = np.zeros((h, w), dtype=bool)
    for _ in range(draw(st.integers(0, 12))):
        r, c = draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1))
        length = draw(st.integers(1, max(h, w)))
        if draw(st.booleans()):
            free[r, c:c + length] = True
        else:
            free[r:r + length, c] = True
    return free


@st.composite
def sparse_grids(draw: st.DrawFn) -> np.ndarray:
    """Random grids at a density chosen to give many small components, or a few large ones."""
    h = draw(st.integers(1, 30))
    w = draw(st.integers(1, 30))
    density = draw(st.sampled_from([0.15, 0.3, 0.45, 0.6, 0.8]))
    seed = draw(st.integers(0, 2**32 - 1))
    return np.random.default_rng(seed).random((h, w)) < density


@settings(max_examples=150, deadline=None)
@given(arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))))
def test_components_match_scipy(free: np.ndarray) -> None:
    assert_matches_oracle(free)


@settings(max_examples=150, deadline=None)
@given(corridor_grids())
def test_components_of_one_cell_corridors_match_scipy(free: np.ndarray) -> None:
    assert_matches_oracle(free)


@settings(max_examples=150, deadline=None)
@given(sparse_grids())
def test_many_components_match_scipy(free: np.ndarray) -> None:
    assert_matches_oracle(free)


def serpentine(h: int, w: int) -> np.ndarray:
    """One one-cell corridor that snakes through every other row: the longest path a grid has."""
    free = np.zeros((h, w), dtype=bool)
    free[::2, :] = True
    for r in range(1, h, 2):
        free[r, w - 1 if r % 4 == 1 else 0] = True
    return free


@pytest.mark.parametrize("name", ["open", "random", "checkerboard", "serpentine"])
def test_benchmark_sized_grids_match_scipy(name: str) -> None:
    # 200 x 200 cells (a 400 x 400 sub-cell map), the largest the benchmarks plan on
    n = 200
    free = {
        "open": np.ones((n, n), dtype=bool),
        "random": np.random.default_rng(7).random((n, n)) < 0.55,
        "checkerboard": np.add.outer(np.arange(n), np.arange(n)) % 2 == 0,
        "serpentine": serpentine(n, n),
    }[name]
    assert_matches_oracle(free)
    if name == "serpentine":
        assert label_components(free)[1] == 1


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 14), st.integers(1, 14), st.integers(0, 2**32 - 1),
       st.sampled_from([0.2, 0.5, 0.8]))
def test_linked_components_match_scipy(h: int, w: int, seed: int, keep: float) -> None:
    # Random subsets of the edges, including edges that touch cells outside ``cells``
    # (which must be ignored), as check_tree sees a tree's edges.
    rng = np.random.default_rng(seed)
    cells = rng.random((h, w)) < 0.8
    right = rng.random((h, w)) < keep
    down = rng.random((h, w)) < keep
    labels, count = label_linked(cells, right, down)
    oracle, oracle_count = oracle_labels(cells, right, down)
    assert count == oracle_count
    assert np.array_equal(labels, oracle)


def test_components_are_numbered_in_raster_order_of_first_cell() -> None:
    free = parse_ascii("#..#.\n##.#.\n.#...\n").free
    labels, count = label_components(free)
    # the right-hand column joins the middle blob through row 2; (2, 0) is alone
    assert count == 2
    assert labels.tolist() == [[0, 1, 1, 0, 1], [0, 0, 1, 0, 1], [2, 0, 1, 1, 1]]


def test_coarse_cell_is_free_only_if_all_four_sub_cells_are() -> None:
    grid = parse_ascii("....#\n.#...\n.....\n.....\n")
    # cell (0, 0) holds the "#" at (1, 1); the "#" at (0, 4) lies in the dropped odd column
    assert coarsen(grid).free.tolist() == [[False, True], [True, True]]


def test_work_area_is_the_robots_component() -> None:
    grid = parse_ascii("..##..\n..##..\n..##..\n..##..\n")
    area = work_area(grid, [(0, 0), (3, 1)])
    assert area.cell_count == 2 and area.n == 8
    assert area.sub_cells[:, :2].all() and not area.sub_cells[:, 2:].any()


@pytest.mark.parametrize(("text", "starts", "error", "needle"), [
    ("##\n##\n", [(0, 0)], EmptyMapError, "no free cell"),
    ("..\n..\n", [(0, 0), (0, 0)], RobotPlacementError, "both start"),
    ("..#.\n....\n", [(0, 2)], RobotPlacementError, "obstacle"),
    ("..#.\n....\n", [(0, 3)], RobotPlacementError, "discarded"),
    ("..##..\n..##..\n", [(0, 0), (0, 5)], DisconnectedRobotsError, "disconnected"),
    ("..\n..\n", [], RobotPlacementError, "no robots"),
])
def test_work_area_errors_are_specific(text: str, starts: list[tuple[int, int]],
                                       error: type[Exception], needle: str) -> None:
    with pytest.raises(error, match=needle):
        work_area(parse_ascii(text), starts)


def test_odd_edge_rows_are_dropped() -> None:
    grid = OccupancyGrid(np.ones((5, 3), dtype=bool))
    assert coarsen(grid).shape == (2, 1)


def test_random_starts_one_per_cell_never_shares_a_coarse_cell() -> None:
    from planner.maps import resolve_world
    from planner.placement import random_starts

    grid = resolve_world("cave")
    for seed in range(40):
        starts = random_starts(grid, 6, seed, one_per_cell=True)
        cells = {(r // 2, c // 2) for r, c in starts}
        assert len(cells) == 6, (seed, starts)


@pytest.mark.parametrize("seed", range(4))
def test_breadth_first_matches_the_breadth_first_oracle(seed: int) -> None:
    """Whole-array steps from several sources over a grid 35 % blocked at random: every
    open cell's distance is the oracle's, FAR where no way leads."""
    rng = np.random.default_rng(seed)
    free = rng.random((17, 23)) > 0.35
    cells = [(int(r), int(c)) for r, c in np.argwhere(free)]
    sources = [cells[int(i)] for i in rng.choice(len(cells), size=3, replace=False)]
    mask = np.zeros(free.shape, dtype=bool)
    for s in sources:
        mask[s] = True
    dist = breadth_first(free, mask)
    expected = grid_distances(free, sources)
    for cell in cells:
        assert dist[cell] == expected.get(cell, FAR), cell
    assert (dist[~free] == FAR).all()
