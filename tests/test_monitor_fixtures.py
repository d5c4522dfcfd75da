"""Scripted missions for the monitor tests: the messages a fleet would send, built naively.

The oracle is the scripted walks themselves: visit counts, moves and revisits are counted
here by brute force, independently of deploy.monitor.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from bus import keys
from bus.messages import (
    CoverEvent,
    DeathNotice,
    GroundTruthPose,
    Heartbeat,
    MissionStatus,
    Progress,
    RobotEvent,
    RobotStatus,
    RobotTruth,
    WorldState,
    make_world_state,
)
from deploy.monitor.types import Record, TokenChange

M = "test"
SubCell = tuple[int, int]


def snake(rows: range, cols: range) -> list[SubCell]:
    """A boustrophedon walk over a rectangle of sub-cells (4-adjacent steps)."""
    out: list[SubCell] = []
    for i, r in enumerate(rows):
        out += [(r, c) for c in (cols if i % 2 == 0 else reversed(cols))]
    return out


@dataclass
class Mission:
    """Records of a scripted mission and the brute-force truth about it."""

    free: np.ndarray
    walks: dict[int, list[SubCell]]
    algo: str = "nb"
    records: list[Record] = field(default_factory=list)
    t: float = 0.0
    log: list[tuple[int, SubCell]] = field(default_factory=list)  # every entry, in order

    def add(self, key: str, msg: object, via: str = "sub", dt: float = 0.01) -> None:
        self.t += dt
        self.records.append(Record(round(self.t, 6), key, msg, via))  # type: ignore[arg-type]

    def visits(self, upto: dict[int, int] | None = None) -> Counter[SubCell]:
        count: Counter[SubCell] = Counter()
        for r, walk in self.walks.items():
            count.update(walk[: None if upto is None else upto.get(r, len(walk))])
        return count

    def world(self, upto: dict[int, int] | None = None, failed: tuple[int, ...] = ()
              ) -> WorldState:
        visits = np.zeros(self.free.shape, dtype=np.int64)
        for cell, n in self.visits(upto).items():
            visits[cell] = n
        robots = []
        for r, walk in sorted(self.walks.items()):
            walked = walk[: None if upto is None else upto.get(r, len(walk))]
            robots.append(RobotTruth(r, (*walked[-1], 1), r not in failed, False,
                                     r in failed, len(walked)))
        first, crossed = self.firsts(upto)
        return make_world_state("script", self.free, visits, tuple(robots), self.t, 0.0,
                                first=first, crossed=crossed)

    def firsts(self, upto: dict[int, int] | None = None
               ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """First visitor per sub-cell and first crosser per cell border (255: nobody), by
        replaying the entries in the order they were made."""
        h, w = self.free.shape
        first = np.full((h, w), 255, np.uint8)
        right = np.full((h // 2, w // 2 - 1), 255, np.uint8)
        down = np.full((h // 2 - 1, w // 2), 255, np.uint8)
        taken: Counter[int] = Counter()
        last: dict[int, SubCell] = {}
        for r, cell in self.log:
            if upto is not None and taken[r] >= upto.get(r, len(self.walks[r])):
                continue
            taken[r] += 1
            if first[cell] == 255:
                first[cell] = r
            if r in last:
                (a, b), (c, d) = (last[r][0] // 2, last[r][1] // 2), (cell[0] // 2, cell[1] // 2)
                if (a, b) != (c, d):
                    border = right if a == c else down
                    if border[min(a, c), min(b, d)] == 255:
                        border[min(a, c), min(b, d)] = r
            last[r] = cell
        return first, (right, down)


def run_mission(free: np.ndarray, walks: dict[int, list[SubCell]], algo: str = "nb",
                kill: tuple[int, int] | None = None, taker: int | None = None,
                digest: str = "d" * 8) -> Mission:
    """Interleave the robots' walks one step each; ``kill=(robot, step)`` stops that robot
    at that step (token lost, then a death notice by ``taker``, who takes over). Every
    robot announces plan digest ``digest``."""
    mission = Mission(free, walks, algo)
    add = mission.add
    mission.add(keys.world(M), mission.world({r: 1 for r in walks}), "query")
    seen: Counter[SubCell] = Counter()
    for r, walk in walks.items():
        seen[walk[0]] += 1
        add(keys.alive(M, r, 1), TokenChange(r, 1, True), "token")
        add(keys.status(M, r), RobotStatus(r, 1, walk[0], algo, digest, "covering"))
        add(keys.sim_cover(M, r), CoverEvent(r, walk[0], 0.0, seen[walk[0]]))
        mission.log.append((r, walk[0]))
    stopped: dict[int, int] = {}
    for step in range(1, max(len(w) for w in walks.values())):
        for r, walk in walks.items():
            if kill is not None and r == kill[0] and step == kill[1]:
                stopped[r] = step
                add(keys.alive(M, r, 1), TokenChange(r, 1, False), "token")
                add(keys.death(M, r), DeathNotice(r, 1, taker, "token", 5.0), dt=0.1)
                add(keys.events(M, taker or 0), RobotEvent(taker or 0, 1, "takeover_started", r))
            if step >= len(walk) or r in stopped:
                continue
            cell = walk[step]
            seen[cell] += 1
            add(keys.sim_pose(M, r), GroundTruthPose(r, (*cell, 1), step * 2.0))
            add(keys.sim_cover(M, r), CoverEvent(r, cell, step * 2.0, seen[cell]))
            mission.log.append((r, cell))
            add(keys.progress(M, r), Progress(r, 1, step, cell, step * 2.0))
            add(keys.heartbeat(M, r), Heartbeat(r, 1, step, (*cell, 1), "covering", step * 2.0))
    if kill is not None:
        walks[kill[0]] = walks[kill[0]][: kill[1]]
    for r in walks:
        if r not in stopped:
            add(keys.events(M, r), RobotEvent(r, 1, "completed", None, "done"))
    add(keys.mission_status(M), MissionStatus("complete", "all covered"))
    add(keys.world(M), mission.world(), "query")
    return mission


def open_room(h: int = 4, w: int = 8) -> np.ndarray:
    return np.ones((h, w), dtype=bool)


def two_robot_walks() -> dict[int, list[SubCell]]:
    """Robot 0 snakes over the left half of a 4 x 8 room, robot 1 over the right half."""
    return {0: snake(range(4), range(4)), 1: snake(range(4), range(4, 8))}
