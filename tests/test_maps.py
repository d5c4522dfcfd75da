"""Map loading: golden grids per format, one test per malformed input, discretization rule,
ROS thresholds, builtin worlds, and the TMSTC* benchmark maps' published cell counts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from PIL import Image

from planner.errors import MapFormatError, MapReadError, PlannerError
from planner.grid import coarsen, expand, label_components
from planner.maps import BUILTIN_WORLDS, builtin_world, load_map, parse_ascii, resolve_world
from planner.maps.discretize import downsample

SHARED_TMSTC = Path(__file__).resolve().parents[1].parent / "shared" / "maps" / "tmstc"

F, B = True, False  # free, blocked: makes expected grids readable


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def save_grey(path: Path, values: list[list[int]]) -> Path:
    Image.fromarray(np.array(values, dtype=np.uint8), mode="L").save(path)
    return path


ROS_YAML = """image: {image}
resolution: {resolution}
origin: [-1.0, 2.5, 0.0]
negate: {negate}
occupied_thresh: 0.65
free_thresh: 0.196
"""


def ros_yaml(tmp_path: Path, image: str = "m.pgm", negate: int = 0,
             resolution: float = 0.05, text: str | None = None) -> Path:
    body = text if text is not None else ROS_YAML.format(image=image, negate=negate,
                                                         resolution=resolution)
    return write(tmp_path / "m.yaml", body)


# ---------------------------------------------------------------- plain ASCII


def test_ascii_golden_with_trailing_whitespace_and_blank_lines() -> None:
    grid = parse_ascii("..#.  \n.@..\t\r\n....\n\n\n")
    assert grid.free.tolist() == [[F, F, B, F], [F, B, F, F], [F, F, F, F]]


def test_load_ascii_file_by_suffix_names_grid_after_stem(tmp_path: Path) -> None:
    for suffix in (".txt", ".ascii"):
        grid = load_map(write(tmp_path / f"lab{suffix}", "#.\n.#\n"))
        assert grid.free.tolist() == [[B, F], [F, B]]
        assert grid.name == "lab"
    assert load_map(tmp_path / "lab.txt", name="other").name == "other"


def test_ascii_ragged_row_names_line_and_lengths() -> None:
    with pytest.raises(MapFormatError) as err:
        parse_ascii("....\n....\n...\n", source="room.txt")
    message = str(err.value)
    assert message.startswith("room.txt:3:")
    assert "3 characters" in message and "expected 4" in message


def test_ascii_unknown_character_names_line_column_and_char() -> None:
    with pytest.raises(MapFormatError) as err:
        parse_ascii("....\n..x.\n", source="room.txt")
    assert str(err.value).startswith("room.txt:2:3:")
    assert "'x'" in str(err.value)
    assert (err.value.line, err.value.column) == (2, 3)


def test_ascii_empty_and_blank_first_row_are_errors() -> None:
    with pytest.raises(MapFormatError, match="empty map"):
        parse_ascii("\n  \n", source="e.txt")
    with pytest.raises(MapFormatError, match=r"e\.txt:1: first row is blank"):
        parse_ascii("\n..\n", source="e.txt")


def test_non_utf8_text_names_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_bytes(b"..\n.\xff\n")
    with pytest.raises(MapFormatError, match=r"bad\.txt:2: not UTF-8"):
        load_map(path)


# ---------------------------------------------------------------- Moving AI


MOVINGAI = "type octile\nheight 3\nwidth 5\nmap\n.GS@O\nTW...\n.....\n"


def test_movingai_golden(tmp_path: Path) -> None:
    grid = load_map(write(tmp_path / "arena.map", MOVINGAI))
    assert grid.free.tolist() == [[F, F, F, B, B], [B, B, F, F, F], [F, F, F, F, F]]


@pytest.mark.parametrize(("text", "line", "expected"), [
    ("type grid\nheight 1\nwidth 1\nmap\n.\n", 1, "expected 'type octile'"),
    ("type octile\nwidth 1\nheight 1\nmap\n.\n", 2, "expected 'height <value>'"),
    ("type octile\nheight 1\nwidth x\nmap\n.\n", 3, "width must be a positive integer"),
    ("type octile\nheight 1\nwidth 1\n.\n", 4, "expected 'map'"),
    ("type octile\nheight 3\nwidth 2\nmap\n..\n..\n", 7, "expected 3 rows"),
    ("type octile\nheight 1\nwidth 2\nmap\n..\n..\n", 6, "expected end of map"),
    ("type octile\nheight 2\nwidth 3\nmap\n...\n....\n", 6, "expected 3 (width 3)"),
    ("type octile\n", 2, "got end of file"),
])
def test_movingai_header_and_row_errors_name_line(tmp_path: Path, text: str, line: int,
                                                  expected: str) -> None:
    path = write(tmp_path / "bad.map", text)
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    assert str(err.value).startswith(f"{path}:{line}:")
    assert expected in str(err.value)


def test_movingai_unknown_character_names_column(tmp_path: Path) -> None:
    path = write(tmp_path / "bad.map", "type octile\nheight 2\nwidth 3\nmap\n...\n.#.\n")
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    assert str(err.value).startswith(f"{path}:6:2:")
    assert "'#'" in str(err.value)


# ---------------------------------------------------------------- images and ROS


def brute_downsample(free: np.ndarray, size: int) -> np.ndarray:
    rows, cols = free.shape[0] // size, free.shape[1] // size
    out = np.zeros((rows, cols), dtype=bool)
    for r in range(rows):
        for c in range(cols):
            out[r, c] = all(free[r * size + i, c * size + j]
                            for i in range(size) for j in range(size))
    return out


@settings(max_examples=60, deadline=None)
@given(free=arrays(np.bool_, st.tuples(st.integers(1, 13), st.integers(1, 13)),
                   elements=st.booleans()),
       size=st.integers(1, 4))
def test_downsample_matches_brute_force(free: np.ndarray, size: int) -> None:
    if free.shape[0] < size or free.shape[1] < size:
        with pytest.raises(MapFormatError, match="no whole"):
            downsample(free, size, "x.png")
    else:
        assert np.array_equal(downsample(free, size, "x.png"), brute_downsample(free, size))


def test_one_dark_pixel_blocks_its_sub_cell_and_partial_blocks_drop(tmp_path: Path) -> None:
    pixels = np.full((5, 7), 255, dtype=np.uint8)  # 2 x 3 whole 2 x 2 blocks, 1 row/col left
    pixels[3, 2] = 0  # in sub-cell (1, 1)
    pixels[4, 0] = 0  # trailing row: dropped, must not block anything
    pixels[0, 6] = 0  # trailing column: dropped
    path = tmp_path / "m.png"
    Image.fromarray(pixels, mode="L").save(path)
    grid = load_map(path, cell_size=2)
    assert grid.free.tolist() == [[F, F, F], [F, B, F]]


def test_plain_image_uses_ros_default_thresholds(tmp_path: Path) -> None:
    # p = (255 - v) / 255: 206 -> 0.192 < 0.196 free; 205 -> 0.196078 not free; 229 free.
    path = save_grey(tmp_path / "m.pgm", [[255, 229, 206, 205, 100, 0]])
    assert load_map(path).free.tolist() == [[F, F, F, B, B, B]]


def test_16_bit_image_uses_its_full_range(tmp_path: Path) -> None:
    # p = (65535 - v) / 65535: 52700 -> 0.1958 free; 52685 -> 0.19608 not free.
    path = tmp_path / "m.png"
    Image.fromarray(np.array([[65535, 52700, 52685, 0]], dtype=np.uint16)).save(path)
    assert load_map(path).free.tolist() == [[F, F, B, B]]


def test_rgb_is_converted_to_luminance(tmp_path: Path) -> None:
    # Pure red has luma 76 (ITU-R 601-2): dark, so blocked although its red channel is 255.
    rgb = np.array([[[255, 255, 255], [255, 0, 0], [229, 229, 229], [0, 0, 0]]], np.uint8)
    path = tmp_path / "m.png"
    Image.fromarray(rgb, mode="RGB").save(path)
    assert load_map(path).free.tolist() == [[F, B, F, B]]


def test_rgba_transparent_pixel_is_obstacle(tmp_path: Path) -> None:
    rgba = np.array([[[255, 255, 255, 255], [255, 255, 255, 0], [255, 255, 255, 1]]], np.uint8)
    path = tmp_path / "m.png"
    Image.fromarray(rgba, mode="RGBA").save(path)
    assert load_map(path).free.tolist() == [[F, B, F]]


def test_ros_yaml_thresholds_and_relative_image(tmp_path: Path) -> None:
    save_grey(tmp_path / "m.pgm", [[255, 206, 205, 0]])
    assert load_map(ros_yaml(tmp_path)).free.tolist() == [[F, F, B, B]]


def test_ros_yaml_negate_flips_occupancy(tmp_path: Path) -> None:
    # negate: p = v / 255, so dark is free: 49 -> 0.192 free, 50 -> 0.196078 not.
    save_grey(tmp_path / "m.pgm", [[0, 49, 50, 255]])
    assert load_map(ros_yaml(tmp_path, negate=1)).free.tolist() == [[F, F, B, B]]


def test_ros_yaml_tool_width_sets_cell_size(tmp_path: Path) -> None:
    pixels = [[255] * 4 for _ in range(4)]
    pixels[0][3] = 0
    save_grey(tmp_path / "m.pgm", pixels)
    path = ros_yaml(tmp_path, resolution=0.05)
    grid = load_map(path, tool_width=0.1)  # 0.1 m / 0.05 m per px = 2 px per sub-cell
    assert grid.free.tolist() == [[F, B], [F, F]]
    assert np.array_equal(load_map(path, 2, tool_width=0.1).free, grid.free)
    with pytest.raises(MapFormatError, match="disagrees with tool_width"):
        load_map(path, 3, tool_width=0.1)


def test_tool_width_needs_ros_yaml(tmp_path: Path) -> None:
    path = save_grey(tmp_path / "m.png", [[255]])
    with pytest.raises(MapFormatError, match="tool_width needs the map's resolution"):
        load_map(path, tool_width=0.5)


@pytest.mark.parametrize(("text", "key", "line"), [
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\nfree_thresh: 0.1\n",
     "occupied_thresh", None),
    (ROS_YAML.format(image="m.pgm", negate=0, resolution="fast"), "resolution", 2),
    (ROS_YAML.format(image="m.pgm", negate=2, resolution=0.05), "negate", 4),
    (ROS_YAML.format(image="[1]", negate=0, resolution=0.05), "image", 1),
    (ROS_YAML.format(image="m.pgm", negate=0, resolution=0.05).replace(
        "[-1.0, 2.5, 0.0]", "[1, 2]"), "origin", 3),
    (ROS_YAML.format(image="m.pgm", negate=0, resolution=0.05).replace(
        "0.196", "1.5"), "free_thresh", 6),
    (ROS_YAML.format(image="m.pgm", negate=0, resolution=0.05) + "mode: raw\n", "mode", 7),
])
def test_ros_yaml_bad_key_is_named(tmp_path: Path, text: str, key: str,
                                   line: int | None) -> None:
    save_grey(tmp_path / "m.pgm", [[255]])
    path = ros_yaml(tmp_path, text=text)
    with pytest.raises(MapFormatError) as err:
        load_map(path)
    assert f"'{key}'" in str(err.value)
    prefix = f"{path}:{line}:" if line is not None else f"{path}: missing key"
    assert str(err.value).startswith(prefix)


def test_ros_yaml_syntax_error_and_non_mapping(tmp_path: Path) -> None:
    path = ros_yaml(tmp_path, text="image: [unclosed\n")
    with pytest.raises(MapFormatError, match=rf"^{path}:\d+:\d+: invalid YAML"):
        load_map(path)
    path = ros_yaml(tmp_path, text="- just\n- a list\n")
    with pytest.raises(MapFormatError, match="expected a mapping"):
        load_map(path)


def test_ros_yaml_missing_image_names_image_path(tmp_path: Path) -> None:
    with pytest.raises(MapReadError, match=r"nothere\.pgm: no such map file"):
        load_map(ros_yaml(tmp_path, image="nothere.pgm"))


def test_corrupt_image_is_a_format_error(tmp_path: Path) -> None:
    path = write(tmp_path / "m.png", "not a png")
    with pytest.raises(MapFormatError, match=r"m\.png: not an image"):
        load_map(path)


# ---------------------------------------------------------------- dispatch and files


def test_unknown_suffix_lists_accepted_ones(tmp_path: Path) -> None:
    with pytest.raises(MapFormatError) as err:
        load_map(write(tmp_path / "m.csv", "."))
    assert "'.csv'" in str(err.value)
    for suffix in (".txt", ".ascii", ".map", ".yaml", ".yml", ".pgm", ".png"):
        assert suffix in str(err.value)


def test_missing_file_and_directory_are_read_errors(tmp_path: Path) -> None:
    missing = tmp_path / "none.txt"
    with pytest.raises(MapReadError, match="no such map file") as err:
        load_map(missing)
    assert err.value.path == str(missing)
    folder = tmp_path / "dir.txt"
    folder.mkdir()
    with pytest.raises(MapReadError, match="is a directory"):
        load_map(folder)


@pytest.mark.parametrize("size", [0, -1, True])
def test_bad_cell_size_is_a_planner_error(tmp_path: Path, size: int) -> None:
    with pytest.raises(PlannerError, match="cell_size must be a positive integer"):
        load_map(write(tmp_path / "m.txt", "..\n..\n"), cell_size=size)


def test_cell_size_applies_to_text_maps(tmp_path: Path) -> None:
    grid = load_map(write(tmp_path / "m.txt", "..#.\n....\n"), cell_size=2)
    assert grid.free.tolist() == [[F, B]]


# ---------------------------------------------------------------- builtin worlds


@pytest.mark.parametrize("name", BUILTIN_WORLDS)
def test_builtin_world_is_even_and_one_connected_area(name: str) -> None:
    grid = builtin_world(name)
    assert grid.name == name
    assert grid.shape[0] % 2 == 0 and grid.shape[1] % 2 == 0
    coarse = coarsen(grid)
    _, cell_parts = label_components(coarse.free)
    _, sub_parts = label_components(grid.free)
    assert (cell_parts, sub_parts) == (1, 1)


@pytest.mark.parametrize("name", [n for n in BUILTIN_WORLDS if n != "cave"])
def test_builtin_world_obstacles_align_to_cells(name: str) -> None:
    grid = builtin_world(name)
    assert np.array_equal(expand(coarsen(grid).free), grid.free)


def test_cave_has_partly_blocked_cells_on_purpose() -> None:
    # Paper 004: a partly occupied cell is not covered; the cave exercises that rule.
    grid = builtin_world("cave")
    assert grid.free.sum() > 4 * coarsen(grid).cell_count


def test_grid30x20_is_paper_003_empty_grid() -> None:
    grid = builtin_world("grid30x20")
    assert coarsen(grid).shape == (20, 30) and grid.free.all() and grid.free.size == 2400


def test_resolve_world_builtin_file_and_unknown(tmp_path: Path) -> None:
    assert np.array_equal(resolve_world("office").free, builtin_world("office").free)
    half = resolve_world("open-room", cell_size=2)
    assert half.shape == (10, 15) and half.free.all()
    path = write(tmp_path / "w.txt", "..\n.#\n")
    assert resolve_world(str(path)).free.tolist() == [[F, F], [F, B]]
    with pytest.raises(MapReadError) as err:
        resolve_world("ofice")
    for name in BUILTIN_WORLDS:
        assert name in str(err.value)
    with pytest.raises(MapReadError, match="unknown builtin world"):
        builtin_world("ofice")


# ---------------------------------------------------------------- TMSTC* benchmark maps


@pytest.mark.skipif(not SHARED_TMSTC.is_dir(), reason=f"benchmark maps absent ({SHARED_TMSTC})")
@pytest.mark.parametrize(("file", "sub_shape", "cell_shape", "free_cells"), [
    # README: indoor 560 x 460 px (width x height) -> 46 rows x 56 cols of sub-cells.
    ("indoor_real.pgm", (46, 56), (23, 28), None),
    ("indoor_real.png", (46, 56), (23, 28), None),
    # 20 x 20 interior with 10 % obstacles inside a one-cell border.
    ("random_20_10.pgm", (44, 44), (22, 22), 360),
    ("random_20_10.png", (44, 44), (22, 22), 360),
    ("Denver_2_1024.png", (107, 107), (53, 53), 1626),
    ("NewYork_0_1024.png", (107, 107), (53, 53), 1643),
])
def test_tmstc_maps_match_their_readme(file: str, sub_shape: tuple[int, int],
                                       cell_shape: tuple[int, int],
                                       free_cells: int | None) -> None:
    grid = load_map(SHARED_TMSTC / file, cell_size=10)
    coarse = coarsen(grid)
    assert grid.shape == sub_shape and coarse.shape == cell_shape
    if free_cells is not None:
        assert coarse.cell_count == free_cells


@pytest.mark.skipif(not SHARED_TMSTC.is_dir(), reason=f"benchmark maps absent ({SHARED_TMSTC})")
def test_indoor_pgm_and_png_agree() -> None:
    pgm = load_map(SHARED_TMSTC / "indoor_real.pgm", cell_size=10)
    png = load_map(SHARED_TMSTC / "indoor_real.png", cell_size=10)
    assert np.array_equal(pgm.free, png.free)
