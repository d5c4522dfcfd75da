"""``mstc simhw`` argument handling: building the world, and one-line user errors."""

from __future__ import annotations

import argparse

import pytest

from planner.errors import PlannerError
from simhw.main import add_arguments, build_world
from simhw.types import Heading, SonarMode


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(list(argv))


def test_explicit_robots_headings_and_sensor_options() -> None:
    world = build_world(parse("--world", "example", "--robots", "0,0;2,10",
                              "--headings", "E,s", "--sonar-mode", "one-at-a-time",
                              "--sonar-range", "3", "--odometry-noise", "0.1"))
    assert [b.pose.as_tuple() for b in world.bodies()] == [(0, 0, 1), (2, 10, 2)]
    assert world.config.sonar_mode is SonarMode.ONE_AT_A_TIME
    assert world.config.sonar_range == 3 and world.config.odometry_noise == 0.1


def test_random_robots_are_seeded_and_valid() -> None:
    a = build_world(parse("--world", "example", "--random-robots", "5", "--seed", "4"))
    b = build_world(parse("--world", "example", "--random-robots", "5", "--seed", "4"))
    c = build_world(parse("--world", "example", "--random-robots", "5", "--seed", "5"))
    poses = [x.pose for x in a.bodies()]
    assert poses == [x.pose for x in b.bodies()] != [x.pose for x in c.bodies()]
    assert len({p.sub for p in poses}) == 5 and all(a.grid.free[p.sub] for p in poses)
    assert all(p.heading is Heading.N for p in poses)


@pytest.mark.parametrize("argv", [
    ("--world", "no-such-world", "--robots", "0,0"),
    ("--world", "example", "--robots", "0,0;0,0"),
    ("--world", "example", "--robots", "0,0", "--headings", "N,E"),
    ("--world", "example", "--robots=-1,0"),
    ("--world", "example", "--robots", "zero"),
])
def test_user_mistakes_are_planner_errors(argv: tuple[str, ...]) -> None:
    with pytest.raises(PlannerError):
        build_world(parse(*argv))


@pytest.mark.parametrize("argv", [
    ("--world", "example"),
    ("--world", "example", "--robots", "0,0", "--random-robots", "2"),
    ("--world", "example", "--robots", "0,0", "--time-scale", "-2"),
    ("--world", "example", "--robots", "0,0", "--headings", "up"),
    ("--world", "example", "--robots", "0,0", "--sonar-range", "0"),
    ("--world", "example", "--robots", "0,0", "--odometry-noise", "nan"),
])
def test_bad_options_are_usage_errors(argv: tuple[str, ...]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        parse(*argv)
    assert exit_info.value.code == 2
