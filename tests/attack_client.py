"""A hostile Zenoh client for the security tests: it listens to a mission to learn robot ids
and incarnations, then forges death notices, heartbeats, statuses and progress for every
robot, publishes garbage and floods on every key family, serves forged state, declares
tokens, and asks the hardware to fail bodies. Run as a process:

    python tests/attack_client.py ENDPOINT MISSION SECONDS [--credentials FILE --role ROLE]

Prints ``refused`` and exits 3 when the router refuses the session, otherwise prints what it
tried (``attacked: N puts``) and exits 0 after SECONDS.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path

import zenoh

from bus import keys
from bus.codec import encode
from bus.config import ConnectionSettings, insert_values, make_zenoh_config
from bus.messages import (
    AdminCommand,
    DeathNotice,
    Heartbeat,
    HwCommand,
    Progress,
    RobotStatus,
)
from bus.messages.schema import ALIVE, FAMILIES

ROBOTS = range(12)  # more than any test fleet: ids it never heard of too


class Intel:
    """Robot -> incarnations heard (from tokens, heartbeats, statuses)."""

    def __init__(self) -> None:
        self.lives: dict[int, set[int]] = {}
        self.heard = 0
        self._lock = threading.Lock()

    def on_sample(self, sample: zenoh.Sample) -> None:
        parsed = keys.parse(str(sample.key_expr))
        with self._lock:
            self.heard += 1
            if parsed is not None and parsed.robot is not None:
                incarnation = parsed.incarnation if parsed.incarnation is not None else 1
                self.lives.setdefault(parsed.robot, set()).add(incarnation)

    def snapshot(self) -> dict[int, set[int]]:
        with self._lock:
            return {robot: set(lives) for robot, lives in self.lives.items()}


def _open(endpoint: str, mission: str, creds: Path | None,
          role: str | None) -> zenoh.Session | None:
    settings = ConnectionSettings(connect=(endpoint,), mission=mission, credentials=creds,
                                  role=role)
    config = make_zenoh_config(settings)
    insert_values(config, {"connect/timeout_ms": 3000, "connect/exit_on_failure": True})
    try:
        return zenoh.open(config)
    except zenoh.ZError:
        return None


def _garbage_keys(mission: str) -> list[str]:
    out = []
    for fam in (*FAMILIES, ALIVE):
        for robot in ROBOTS:
            key = keys.of_robot(fam.label, mission, robot).replace("*", "1")
            if key not in out:
                out.append(key)
    return out


def attack(session: zenoh.Session, mission: str, seconds: float, intel: Intel) -> int:
    puts = 0
    garbage = _garbage_keys(mission)
    blobs = [b"", b"\x00\xff", b"\x91" * 5000 + b"\xc0", b"\xdd\xff\xff\xff\xff",
             b"x" * 70_000]
    tokens = [session.liveliness().declare_token(keys.alive(mission, r, 999)) for r in ROBOTS]
    liar = session.declare_queryable(
        keys.state(mission, 0),
        lambda q: q.reply(keys.state(mission, 0), encode(DeathNotice(1, 1, 0, "token", 0.0))))
    deadline = time.monotonic() + seconds
    rounds = 0
    try:
        while time.monotonic() < deadline:
            rounds += 1
            lives = intel.snapshot()
            for robot in ROBOTS:
                for incarnation in [*sorted(lives.get(robot, {1}))[-2:], 99]:
                    for detector in (None, (robot + 1) % 4, robot):
                        session.put(keys.death(mission, robot), encode(DeathNotice(
                            robot, incarnation, detector, "token", 0.0)))
                        puts += 1
                    session.put(keys.heartbeat(mission, robot), encode(Heartbeat(
                        robot, incarnation + 1, 1, None, "covering", 0.0)))
                    session.put(keys.status(mission, robot), encode(RobotStatus(
                        robot, incarnation, (0, 0), "opt", "forged", "failed", "forged")))
                    session.put(keys.progress(mission, robot), encode(Progress(
                        robot, incarnation, 10**6, (0, 0), 0.0)))
                    puts += 3
                session.get(keys.hw_cmd(mission, robot), payload=encode(HwCommand(
                    1, robot, 1, "forward")), timeout=0.2)
                session.get(keys.hw_admin(mission), payload=encode(AdminCommand(
                    "fail", robot)), timeout=0.2)
            for key in garbage:
                session.put(key, blobs[rounds % len(blobs)])
                puts += 1
            for _ in range(200):  # a flood on one key
                session.put(keys.heartbeat(mission, rounds % 4), b"\x00")
                puts += 1
            time.sleep(0.05)
    finally:
        liar.undeclare()
        for token in tokens:
            token.undeclare()
    return puts


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("endpoint")
    parser.add_argument("mission")
    parser.add_argument("seconds", type=float)
    parser.add_argument("--credentials", type=Path, default=None)
    parser.add_argument("--role", default=None)
    args = parser.parse_args()
    session = _open(args.endpoint, args.mission, args.credentials, args.role)
    if session is None:
        print("refused", flush=True)
        return 3
    try:
        intel = Intel()
        sub = session.declare_subscriber(keys.everything(args.mission), intel.on_sample)
        watch = session.liveliness().declare_subscriber(keys.all_alive(args.mission),
                                                        intel.on_sample, history=True)
        print("connected", flush=True)
        time.sleep(0.5)
        puts = attack(session, args.mission, args.seconds, intel)
        print(f"attacked: {puts} puts, heard {intel.heard} samples, "
              f"robots {sorted(intel.snapshot())}", flush=True)
        sub.undeclare()
        watch.undeclare()
    finally:
        session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
