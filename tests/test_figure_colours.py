"""Robot colours (deploy.monitor.figures): one map for the live view, the report's and the
plan's pictures and the robotics channels, that tells neighbouring ids apart and does not
repeat (the old palettes repeated after 10, 16 or 20 robots)."""

from __future__ import annotations

import itertools
import math

from deploy.monitor.figures import robot_colour, robot_hex


def _distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return math.dist(a[:3], b[:3])


def test_neighbouring_ids_differ_clearly() -> None:
    colours = [robot_colour(r) for r in range(200)]
    assert min(_distance(a, b) for a, b in itertools.pairwise(colours)) > 0.3


def test_no_two_of_the_first_hundreds_look_the_same() -> None:
    colours = [robot_colour(r) for r in range(300)]
    assert len({robot_hex(r) for r in range(300)}) == 300
    closest = min(_distance(a, b) for a, b in itertools.combinations(colours[:40], 2))
    assert closest > 0.05  # ids 0..39: none of them a repeat of another


def test_hex_is_the_rgba_colour() -> None:
    r, g, b, alpha = robot_colour(7, 0.5)
    assert alpha == 0.5 and robot_hex(7) == "#" + "".join(
        f"{round(255 * x):02x}" for x in (r, g, b))


def test_every_view_colours_a_robot_the_same() -> None:
    from deploy.monitor.view import colour

    assert [colour(r) for r in range(30)] == [robot_hex(r) for r in range(30)]
