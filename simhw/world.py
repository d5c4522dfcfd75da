"""The simulated world: an occupancy grid and k RV-400 bodies, with ground truth.

Pure and synchronous: times are passed in by the caller (the server's clock or a test), the only
randomness is the injected seed for odometry noise. Every operation checks everything first and
mutates only when it succeeds, so a refused command leaves the world as it was.

A forward step is two calls: ``begin_forward`` reserves the target sub-cell (so two bodies can
never enter one sub-cell, whoever finishes first), ``finish_move`` moves the body into it and
logs the coverage. In between, the body holds both sub-cells.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from planner.types import OccupancyGrid
from simhw.errors import BodyBusyError, BodyFailedError, BodyFrozenError, CommandRejected
from simhw.sensors import QUARTER_TURN_RAD, blocked_mask, noisy_odometry, sonar_range
from simhw.types import (
    SENSORS,
    BodyStatus,
    BodyView,
    BumpCause,
    BumpRecord,
    CoverRecord,
    MoveOutcome,
    Pose,
    Side,
    SonarMode,
    SonarReading,
    StepResult,
    SubCell,
    WorldConfig,
)


@dataclass
class _Body:
    pose: Pose
    status: BodyStatus = BodyStatus.ALIVE
    target: SubCell | None = None
    bumper: bool = False
    # A dead robot's body no longer holds its sub-cells (simhw.dead_bodies).
    vanished: bool = False


class World:
    """The grid, the bodies on it and the ground-truth logs (coverage, bumps)."""

    def __init__(self, grid: OccupancyGrid, poses: Sequence[Pose],
                 config: WorldConfig | None = None, seed: int | None = None,
                 start_time: float = 0.0) -> None:
        self.grid = grid
        self.config = config or WorldConfig()
        self._rng = np.random.default_rng(seed)
        self._bodies: list[_Body] = []
        self.visits: npt.NDArray[np.int64] = np.zeros(grid.shape, dtype=np.int64)
        self.cover_log: list[CoverRecord] = []
        self.bump_log: list[BumpRecord] = []
        self.covered = 0  # sub-cells entered at least once
        # robot -> the ``covered`` count at which its body fails (arm_failure), and the
        # failures so fired, as (robot, covered, time)
        self.armed: dict[int, int] = {}
        self.fired: list[tuple[int, int, float]] = []
        # ``covered`` counts at which every body is held (pause_at), whether they are now,
        # and the pauses so far as (covered, time)
        self.checkpoints: set[int] = set()
        self.paused = False
        self.pauses: list[tuple[int, float]] = []
        taken: dict[SubCell, int] = {}
        for robot, pose in enumerate(poses):
            self._check_start(robot, pose, taken)
            taken[pose.sub] = robot
        for pose in poses:
            self._bodies.append(_Body(pose=pose))
        for robot, pose in enumerate(poses):
            self._cover(robot, pose.sub, start_time)

    def _check_start(self, robot: int, pose: Pose, taken: dict[SubCell, int]) -> None:
        # ValueError, not a PlannerError: callers validate user input with planner.placement.
        if not self._inside(pose.sub) or not self.grid.free[pose.sub]:
            raise ValueError(f"robot {robot} cannot start at {pose.sub}: not a free sub-cell")
        if pose.sub in taken:
            raise ValueError(f"robots {taken[pose.sub]} and {robot} both start at {pose.sub}")

    # ---- queries -------------------------------------------------------------------------

    @property
    def k(self) -> int:
        return len(self._bodies)

    def body(self, robot: int) -> BodyView:
        b = self._get(robot)
        return BodyView(robot=robot, pose=b.pose, status=b.status, target=b.target)

    def bodies(self) -> tuple[BodyView, ...]:
        return tuple(self.body(i) for i in range(self.k))

    def bumper(self, robot: int) -> bool:
        """True when the body's last forward step ended against something."""
        return self._get(robot).bumper

    def held(self) -> dict[SubCell, int]:
        """Every sub-cell held by a body (its own, and its reserved target while moving)."""
        out: dict[SubCell, int] = {}
        for robot, b in enumerate(self._bodies):
            if b.vanished:
                continue
            out[b.pose.sub] = robot
            if b.target is not None:
                out[b.target] = robot
        return out

    # ---- motion --------------------------------------------------------------------------

    def begin_forward(self, robot: int, at: float) -> MoveOutcome:
        """Start a one-sub-cell step: reserve the target, or bump and stay (logged)."""
        b = self._ready(robot)
        target = b.pose.ahead()
        cause = self._blocker(robot, target)
        if cause is not None:
            b.bumper = True
            self.bump_log.append(BumpRecord(robot=robot, at=b.pose.sub, into=target,
                                            cause=cause, time=at))
            return MoveOutcome(robot=robot, start=b.pose, target=target, bumped=True,
                               cause=cause)
        b.target = target
        b.bumper = False
        return MoveOutcome(robot=robot, start=b.pose, target=target, bumped=False)

    def finish_move(self, robot: int, at: float) -> StepResult:
        """Complete the step begun by ``begin_forward``: enter the target, log the visit."""
        b = self._get(robot)
        if b.status is BodyStatus.FAILED:
            raise BodyFailedError(f"robot {robot} failed during its motion")
        if b.target is None:
            raise CommandRejected(f"robot {robot} has no motion in progress")
        b.pose = Pose(b.target[0], b.target[1], b.pose.heading)
        b.target = None
        self._cover(robot, b.pose.sub, at)
        odo = noisy_odometry(self.config.sub_cell_m, 0.0, self.config.odometry_noise, self._rng)
        return StepResult(robot=robot, pose=b.pose, odometry=odo)

    def bumped_step(self, robot: int) -> StepResult:
        """The result of a forward step that bumped: same pose, no distance travelled."""
        b = self._get(robot)
        return StepResult(robot=robot, pose=b.pose, odometry=noisy_odometry(
            0.0, 0.0, self.config.odometry_noise, self._rng), bumped=True)

    def turn(self, robot: int, side: Side) -> StepResult:
        """Turn 90 degrees in place; always possible for a body that can act."""
        b = self._ready(robot)
        b.pose = Pose(b.pose.row, b.pose.col, b.pose.heading.turned(side))
        sign = 1.0 if side is Side.LEFT else -1.0  # counter-clockwise positive, as in ROS
        odo = noisy_odometry(0.0, sign * QUARTER_TURN_RAD, self.config.odometry_noise,
                             self._rng)
        return StepResult(robot=robot, pose=b.pose, odometry=odo)

    # ---- sensing -------------------------------------------------------------------------

    def sense(self, robot: int, sensors: Sequence[str]) -> SonarReading:
        """Read the named sonars. In one-at-a-time mode exactly one may be named."""
        b = self._ready(robot)
        wanted = list(dict.fromkeys(sensors))
        unknown = [s for s in wanted if s not in SENSORS]
        if unknown or not wanted:
            raise CommandRejected(
                f"sense needs sensors among {', '.join(SENSORS)}; got {list(sensors)!r}")
        if self.config.sonar_mode is SonarMode.ONE_AT_A_TIME and len(wanted) > 1:
            raise CommandRejected(
                f"sonar mode one-at-a-time reads one direction per command; got {wanted}")
        others = [sub for sub, owner in self.held().items() if owner != robot]
        blocked = blocked_mask(self.grid.free, others)
        return SonarReading(ranges={
            s: sonar_range(blocked, b.pose.sub, b.pose.heading.towards(s),
                           self.config.sonar_range) for s in wanted})

    # ---- failure injection ---------------------------------------------------------------

    def fail(self, robot: int) -> None:
        """Motors dead for good: the body stays where it is, a motion in progress is undone."""
        b = self._get(robot)
        b.status = BodyStatus.FAILED
        b.target = None
        self.armed.pop(robot, None)

    def arm_failure(self, robot: int, covered: int, at: float) -> bool:
        """Fail ``robot``'s body the moment ``covered`` sub-cells are covered (right after the
        step that covers the last of them); at once if they already are. True if it failed now.

        A failure ordered at a share of the coverage lands exactly there, however long the
        order takes to arrive: at time scale 0 a whole mission can pass in that time.
        """
        b = self._get(robot)
        if b.status is BodyStatus.FAILED:
            raise BodyFailedError(f"robot {robot} has failed already")
        if self.covered >= covered:
            self._fire(robot, at)
            return True
        self.armed[robot] = covered
        return False

    def _fire(self, robot: int, at: float) -> None:
        self.fail(robot)  # disarms it
        self.fired.append((robot, self.covered, at))

    def pause_at(self, covered: int, at: float) -> bool:
        """Hold every body from the moment ``covered`` sub-cells are covered (right after the
        step that covers the last of them; at once if they already are) until ``resume``:
        the world stands still while a slow operator catches up. True if paused now.

        The world only records it: the server holds the bodies' next commands and the
        arrivals of motions under way (simhw.service).
        """
        if self.covered >= covered:
            self._pause(at)
            return True
        self.checkpoints.add(covered)
        return False

    def resume(self) -> None:
        self.paused = False

    def _pause(self, at: float) -> None:
        self.checkpoints = {c for c in self.checkpoints if c > self.covered}
        self.paused = True
        self.pauses.append((self.covered, at))

    def vanish(self, robot: int) -> None:
        """The robot is dead: its body stops holding sub-cells (no bumps, no sonar echo)."""
        self._get(robot).vanished = True

    def freeze(self, robot: int) -> None:
        b = self._get(robot)
        if b.status is BodyStatus.FAILED:
            raise BodyFailedError(f"robot {robot} has failed; it cannot be frozen")
        b.status = BodyStatus.FROZEN

    def unfreeze(self, robot: int) -> None:
        b = self._get(robot)
        if b.status is BodyStatus.FAILED:
            raise BodyFailedError(f"robot {robot} has failed; it cannot be unfrozen")
        b.status = BodyStatus.ALIVE

    # ---- internals -----------------------------------------------------------------------

    def _get(self, robot: int) -> _Body:
        if not 0 <= robot < len(self._bodies):
            raise CommandRejected(f"no robot {robot}: this world has robots 0..{self.k - 1}")
        return self._bodies[robot]

    def check_ready(self, robot: int) -> None:
        """Raise unless the body can start a motion or a reading now."""
        self._ready(robot)

    def _ready(self, robot: int) -> _Body:
        b = self._get(robot)
        if b.status is BodyStatus.FAILED:
            raise BodyFailedError(f"robot {robot} has failed")
        if b.status is BodyStatus.FROZEN:
            raise BodyFrozenError(f"robot {robot} is frozen")
        if b.target is not None:
            raise BodyBusyError(f"robot {robot} is still moving to {b.target}")
        return b

    def _inside(self, sub: SubCell) -> bool:
        h, w = self.grid.shape
        return 0 <= sub[0] < h and 0 <= sub[1] < w

    def _blocker(self, robot: int, target: SubCell) -> BumpCause | None:
        if not self._inside(target):
            return BumpCause.EDGE
        if not self.grid.free[target]:
            return BumpCause.OBSTACLE
        owner = self.held().get(target)
        if owner is not None and owner != robot:
            return BumpCause.BODY
        return None

    def _cover(self, robot: int, sub: SubCell, at: float) -> None:
        self.visits[sub] += 1
        self.cover_log.append(CoverRecord(robot=robot, sub=sub, time=at,
                                          visits=int(self.visits[sub])))
        if self.visits[sub] == 1:
            self.covered += 1
            for armed, when in sorted(self.armed.items()):
                if self.covered >= when:
                    self._fire(armed, at)
            if any(c <= self.covered for c in self.checkpoints):
                self._pause(at)
