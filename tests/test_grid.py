"""Grid model: coarse cells, components (against scipy.ndimage as an oracle), work-area errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import ndimage

from planner.errors import (
    DisconnectedRobotsError,
    EmptyMapError,
    RobotPlacementError,
)
from planner.grid import coarsen, label_components, work_area
from planner.maps import parse_ascii
from planner.types import OccupancyGrid


@settings(max_examples=150, deadline=None)
@given(arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))))
def test_components_match_ndimage(free: np.ndarray) -> None:
    labels, count = label_components(free)
    oracle, oracle_count = ndimage.label(free)
    assert count == oracle_count
    assert np.array_equal(labels, oracle)  # both number components in raster order


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
