"""The pure simulated world: collisions, reservations, sonar, odometry, failures, ground truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.types import OccupancyGrid
from simhw.errors import BodyBusyError, BodyFailedError, BodyFrozenError, CommandRejected
from simhw.types import (
    SENSORS,
    BodyStatus,
    BumpCause,
    Heading,
    Pose,
    Side,
    SonarMode,
    WorldConfig,
)
from simhw.world import World


def grid(*rows: str) -> OccupancyGrid:
    """'#' is an obstacle, anything else free (tests must not depend on planner.maps)."""
    return OccupancyGrid(np.array([[ch != "#" for ch in row] for row in rows], dtype=bool))


OPEN = grid("......", "......", "......", "......")


def test_forward_moves_one_sub_cell_in_heading_and_logs_cover() -> None:
    w = World(OPEN, [Pose(2, 2, Heading.E)])
    out = w.begin_forward(0, at=0.0)
    assert not out.bumped and out.target == (2, 3)
    step = w.finish_move(0, at=1.5)
    assert step.pose == Pose(2, 3, Heading.E)
    assert w.visits[2, 3] == 1 and w.visits[2, 2] == 1
    assert w.cover_log[-1].sub == (2, 3) and w.cover_log[-1].time == 1.5


@pytest.mark.parametrize(("pose", "cause"), [
    (Pose(0, 0, Heading.N), BumpCause.EDGE),
    (Pose(0, 0, Heading.W), BumpCause.EDGE),
    (Pose(3, 5, Heading.S), BumpCause.EDGE),
    (Pose(3, 5, Heading.E), BumpCause.EDGE),
    (Pose(1, 0, Heading.E), BumpCause.OBSTACLE),
])
def test_bump_leaves_world_unchanged(pose: Pose, cause: BumpCause) -> None:
    g = grid("......", ".#....", "......", "......")
    w = World(g, [pose])
    before = (w.body(0), w.visits.copy(), len(w.cover_log))
    out = w.begin_forward(0, at=3.0)
    assert out.bumped and out.cause is cause
    assert w.bumper(0)
    assert (w.body(0), len(w.cover_log)) == (before[0], before[2])
    assert np.array_equal(w.visits, before[1])
    assert w.bump_log[-1].cause is cause and w.bump_log[-1].at == pose.sub


def test_a_body_blocks_another() -> None:
    w = World(OPEN, [Pose(1, 1, Heading.E), Pose(1, 2, Heading.N)])
    out = w.begin_forward(0, at=0.0)
    assert out.bumped and out.cause is BumpCause.BODY
    assert w.body(0).pose == Pose(1, 1, Heading.E)


def test_reservation_lets_exactly_one_of_two_into_a_sub_cell() -> None:
    # Both aim at (1, 2): the first to start reserves it, the second bumps even though the
    # first has not arrived yet.
    w = World(OPEN, [Pose(1, 1, Heading.E), Pose(1, 3, Heading.W)])
    first = w.begin_forward(1, at=0.0)
    second = w.begin_forward(0, at=0.0)
    assert not first.bumped and second.bumped and second.cause is BumpCause.BODY
    w.finish_move(1, at=1.0)
    assert w.body(1).pose.sub == (1, 2) and w.body(0).pose.sub == (1, 1)


def test_the_origin_stays_held_until_the_move_finishes() -> None:
    w = World(OPEN, [Pose(1, 1, Heading.E), Pose(1, 0, Heading.E)])
    w.begin_forward(0, at=0.0)
    assert w.begin_forward(1, at=0.0).bumped
    w.finish_move(0, at=1.0)
    assert not w.begin_forward(1, at=1.0).bumped


def test_a_moving_body_is_busy() -> None:
    w = World(OPEN, [Pose(1, 1, Heading.E)])
    w.begin_forward(0, at=0.0)
    with pytest.raises(BodyBusyError):
        w.turn(0, Side.LEFT)
    with pytest.raises(BodyBusyError):
        w.begin_forward(0, at=0.0)


def test_finish_without_begin_is_rejected() -> None:
    w = World(OPEN, [Pose(1, 1)])
    with pytest.raises(CommandRejected):
        w.finish_move(0, at=0.0)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(["left", "right"]), max_size=12))
def test_turns_compose_like_quarter_rotations(turns: list[str]) -> None:
    w = World(OPEN, [Pose(2, 2, Heading.N)])
    total = 0.0
    for t in turns:
        step = w.turn(0, Side(t))
        total += step.odometry.turn_rad
    net = sum(1 if t == "right" else -1 for t in turns)
    assert w.body(0).pose == Pose(2, 2, Heading(net % 4))
    # Left is counter-clockwise positive.
    assert math.isclose(total, -net * math.pi / 2, abs_tol=1e-9)


def brute_range(free: np.ndarray, others: set[tuple[int, int]], start: tuple[int, int],
                delta: tuple[int, int], max_range: int) -> int | None:
    r, c = start
    for step in range(1, max_range + 1):
        r, c = r + delta[0], c + delta[1]
        if not (0 <= r < free.shape[0] and 0 <= c < free.shape[1]):
            return step
        if not free[r, c] or (r, c) in others:
            return step
    return None


@settings(max_examples=80, deadline=None)
@given(st.data())
def test_sonar_matches_a_brute_force_walk(data: st.DataObject) -> None:
    h = data.draw(st.integers(2, 9))
    w_ = data.draw(st.integers(2, 9))
    free = np.array(data.draw(st.lists(st.lists(st.booleans(), min_size=w_, max_size=w_),
                                       min_size=h, max_size=h)), dtype=bool)
    cells = [(int(x[0]), int(x[1])) for x in np.argwhere(free)]
    if len(cells) < 2:
        return
    chosen = data.draw(st.lists(st.sampled_from(cells), min_size=1, max_size=3, unique=True))
    heading = Heading(data.draw(st.integers(0, 3)))
    max_range = data.draw(st.integers(1, 10))
    poses = [Pose(r, c, heading) for r, c in chosen]
    world = World(OccupancyGrid(free), poses, WorldConfig(sonar_range=max_range))
    reading = world.sense(0, SENSORS)
    others = set(chosen[1:])
    for sensor in SENSORS:
        expect = brute_range(free, others, chosen[0], heading.towards(sensor).delta, max_range)
        assert reading.ranges[sensor] == expect


def test_sonar_sees_a_reserved_target() -> None:
    w = World(OPEN, [Pose(0, 0, Heading.E), Pose(1, 3, Heading.N)])
    assert w.sense(0, ["front"]).ranges["front"] == 6  # the map edge
    w.begin_forward(1, at=0.0)  # reserves (0, 3)
    assert w.sense(0, ["front"]).ranges["front"] == 3


def test_one_at_a_time_sonar_reads_one_direction_per_command() -> None:
    w = World(OPEN, [Pose(1, 1, Heading.N)], WorldConfig(sonar_mode=SonarMode.ONE_AT_A_TIME))
    assert set(w.sense(0, ["left"]).ranges) == {"left"}
    with pytest.raises(CommandRejected):
        w.sense(0, ["front", "left"])
    full = World(OPEN, [Pose(1, 1, Heading.N)])
    assert set(full.sense(0, SENSORS).ranges) == set(SENSORS)


@pytest.mark.parametrize("sensors", [[], ["back"], ["front", "up"]])
def test_unknown_sensors_are_rejected(sensors: list[str]) -> None:
    w = World(OPEN, [Pose(1, 1)])
    with pytest.raises(CommandRejected):
        w.sense(0, sensors)


def odometry_run(seed: int, sigma: float) -> list[tuple[float, float]]:
    w = World(OPEN, [Pose(2, 0, Heading.E)], WorldConfig(odometry_noise=sigma), seed=seed)
    out = []
    for _ in range(3):
        w.begin_forward(0, at=0.0)
        out.append(w.finish_move(0, at=0.0).odometry)
        out.append(w.turn(0, Side.LEFT).odometry)
        out.append(w.turn(0, Side.RIGHT).odometry)
    return [(o.forward_m, o.turn_rad) for o in out]


def test_odometry_noise_is_seeded_and_reset_per_step() -> None:
    assert odometry_run(7, 0.05) == odometry_run(7, 0.05)
    assert odometry_run(7, 0.05) != odometry_run(8, 0.05)
    exact = odometry_run(7, 0.0)
    d = WorldConfig().sub_cell_m
    # Each step reports its own motion only: nothing accumulates from earlier steps.
    assert exact[0::3] == [(d, 0.0)] * 3
    assert exact[1::3] == [(0.0, math.pi / 2)] * 3
    noisy = odometry_run(7, 0.05)
    assert all(abs(f - d) < 0.5 * d for f, _ in noisy[0::3])
    assert any(f != d for f, _ in noisy[0::3])


def test_noise_statistics_follow_sigma() -> None:
    w = World(grid("." * 3), [Pose(0, 0, Heading.N)], WorldConfig(odometry_noise=0.1), seed=3)
    samples = np.array([w.turn(0, Side.LEFT).odometry.turn_rad for _ in range(2000)])
    rel = samples / (math.pi / 2) - 1.0
    assert abs(rel.mean()) < 0.02 and 0.08 < rel.std() < 0.12


def test_failed_body_stays_and_keeps_its_sub_cell() -> None:
    w = World(OPEN, [Pose(1, 1, Heading.E), Pose(1, 3, Heading.W)])
    w.begin_forward(0, at=0.0)
    w.fail(0)  # mid-motion: the reservation is undone, the body stays where it was
    assert w.body(0).status is BodyStatus.FAILED and w.body(0).pose.sub == (1, 1)
    for op in (lambda: w.begin_forward(0, at=0.0), lambda: w.turn(0, Side.LEFT),
               lambda: w.sense(0, ["front"]), lambda: w.finish_move(0, at=0.0),
               lambda: w.freeze(0)):
        with pytest.raises(BodyFailedError):
            op()
    assert not w.begin_forward(1, at=0.0).bumped  # (1, 2) was released
    w.finish_move(1, at=1.0)
    assert w.begin_forward(1, at=1.0).cause is BumpCause.BODY  # (1, 1) still occupied


def test_frozen_body_refuses_until_unfrozen() -> None:
    w = World(OPEN, [Pose(1, 1, Heading.E)])
    w.freeze(0)
    with pytest.raises(BodyFrozenError):
        w.begin_forward(0, at=0.0)
    with pytest.raises(BodyFrozenError):
        w.sense(0, ["front"])
    w.unfreeze(0)
    assert not w.begin_forward(0, at=0.0).bumped


def test_unknown_robot_is_rejected() -> None:
    w = World(OPEN, [Pose(1, 1)])
    with pytest.raises(CommandRejected):
        w.turn(5, Side.LEFT)
    with pytest.raises(CommandRejected):
        w.fail(-1)


@pytest.mark.parametrize("poses", [[Pose(1, 1), Pose(1, 1)], [Pose(0, 9)], [Pose(1, 1)]])
def test_bad_starts_are_refused(poses: list[Pose]) -> None:
    g = grid("....", ".#..", "....")
    with pytest.raises(ValueError, match="robot"):
        World(g, poses)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.sampled_from(["f", "l", "r", "fail"])),
                max_size=40))
def test_random_command_sequences_keep_invariants(script: list[tuple[int, str]]) -> None:
    g = grid("......", ".#..#.", "......", "..##..")
    w = World(g, [Pose(0, 0, Heading.E), Pose(2, 5, Heading.W), Pose(3, 0, Heading.N)])
    for t, (robot, op) in enumerate(script):
        before = w.body(robot).pose
        try:
            if op == "f":
                if not w.begin_forward(robot, at=float(t)).bumped:
                    after = w.finish_move(robot, at=float(t)).pose
                    # Moves are 4-adjacent, in the heading.
                    assert after.sub == before.ahead()
            elif op == "fail":
                w.fail(robot)
            else:
                w.turn(robot, Side.LEFT if op == "l" else Side.RIGHT)
        except BodyFailedError:
            assert w.body(robot).status is BodyStatus.FAILED
        subs = [b.pose.sub for b in w.bodies()]
        assert len(set(subs)) == len(subs)
        assert all(g.free[s] for s in subs)
    # The coverage log and the visit counts agree.
    counts = np.zeros(g.shape, dtype=int)
    for rec in w.cover_log:
        counts[rec.sub] += 1
        assert rec.visits == counts[rec.sub]
    assert np.array_equal(counts, w.visits)


# ---- failures armed at a coverage (mstc up --kill-hw R@progress=P) ----------------------


def _walk_east(w: World, robot: int, steps: int, at: float = 0.0) -> None:
    for _ in range(steps):
        w.begin_forward(robot, at=at)
        w.finish_move(robot, at=at)


def test_an_armed_failure_fires_right_after_the_step_that_covers_its_count() -> None:
    w = World(OPEN, [Pose(0, 0, Heading.E), Pose(3, 0, Heading.E)])
    assert w.covered == 2  # the starts
    assert not w.arm_failure(1, covered=5, at=0.0)
    _walk_east(w, 0, 2)
    assert w.body(1).status is BodyStatus.ALIVE and w.fired == []
    w.begin_forward(0, at=4.0)
    w.finish_move(0, at=4.0)  # the fifth sub-cell covered: robot 1's motors die now
    assert w.body(1).status is BodyStatus.FAILED
    assert w.fired == [(1, 5, 4.0)] and w.armed == {}
    with pytest.raises(BodyFailedError):
        w.begin_forward(1, at=5.0)


def test_revisits_do_not_count_towards_an_armed_failure() -> None:
    w = World(OPEN, [Pose(0, 0, Heading.E), Pose(3, 0, Heading.E)])
    w.arm_failure(1, covered=4, at=0.0)
    _walk_east(w, 0, 1)  # 3 covered
    for side in (Side.LEFT, Side.LEFT):
        w.turn(0, side)
    _walk_east(w, 0, 1)  # back onto its start: still 3
    assert w.covered == 3 and w.body(1).status is BodyStatus.ALIVE
    w.turn(1, Side.LEFT)
    w.begin_forward(1, at=1.0)
    w.finish_move(1, at=1.0)  # the armed robot's own step can set it off
    assert w.covered == 4 and w.body(1).status is BodyStatus.FAILED
    assert w.body(1).pose.sub == (2, 0)  # it arrived, then failed


def test_an_armed_failure_already_reached_fires_at_once_and_undoes_a_motion() -> None:
    w = World(OPEN, [Pose(0, 0, Heading.E), Pose(3, 0, Heading.E)])
    w.begin_forward(1, at=0.0)  # robot 1 is between two sub-cells
    assert w.arm_failure(1, covered=2, at=1.0)
    assert w.fired == [(1, 2, 1.0)] and w.body(1).target is None
    with pytest.raises(BodyFailedError):
        w.finish_move(1, at=1.5)
    with pytest.raises(BodyFailedError):
        w.arm_failure(1, covered=9, at=2.0)


def test_a_failure_by_hand_disarms_and_failures_due_together_fire_in_robot_order() -> None:
    w = World(OPEN, [Pose(r, 0, Heading.E) for r in range(4)])
    w.arm_failure(3, covered=6, at=0.0)
    w.arm_failure(2, covered=6, at=0.0)
    w.arm_failure(1, covered=7, at=0.0)
    w.fail(1)
    assert w.armed == {3: 6, 2: 6}
    _walk_east(w, 0, 1, at=7.0)
    assert w.fired == []
    _walk_east(w, 0, 1, at=8.0)
    assert w.fired == [(2, 6, 8.0), (3, 6, 8.0)] and w.armed == {}


def test_a_pause_holds_from_the_step_that_covers_its_count_until_resumed() -> None:
    w = World(OPEN, [Pose(0, 0, Heading.E), Pose(3, 0, Heading.E)])
    assert not w.pause_at(4, at=0.0) and not w.paused
    _walk_east(w, 0, 1)
    assert not w.paused
    _walk_east(w, 1, 1, at=3.0)  # the fourth sub-cell
    assert w.paused and w.pauses == [(4, 3.0)] and w.checkpoints == set()
    w.resume()
    assert not w.paused
    assert w.pause_at(2, at=5.0) and w.pauses[-1] == (4, 5.0)  # already there: at once
