"""Dead robots in the world: their lives are fenced at the hardware, their bodies moved aside.

The offline MSTC papers assume that a failed robot does not block the live ones (paper 003,
before Theorem 3): a robot taking over a dead robot's section walks the cycle straight
through where the dead body stopped. simhw implements that assumption when told to
(``--dead-bodies vanish``, the default): on a death notice the body stops holding its
sub-cell, so it neither blocks moves nor shows on sonars. ``block`` keeps it in the way, for
experiments on what the assumption is worth. Either way the dead life is fenced: commands
from its incarnation (or an older one) are refused as stale, so a robot that was only hung
and wakes up cannot cover cells that were handed to others.
"""

from __future__ import annotations

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.messages import DeathNotice
from simhw.service import HwService
from simhw.types import DeadBodies


def on_death(service: HwService, notice: DeathNotice, policy: DeadBodies) -> bool:
    """Apply one death notice; False (and counted) when it names no robot of this world."""
    if not 0 <= notice.robot < service.world.k:
        if service.drops is not None:
            service.drops.count("death", "invalid", f"death of robot {notice.robot}")
        return False
    detector = notice.detected_by
    if detector is not None and detector != notice.robot and service.life_is_fenced(detector):
        # A fenced life's verdict: across a healed partition, the far side declares the near
        # side dead; fencing the near side too would leave no robot able to move.
        if service.drops is not None:
            service.drops.count("death", "dead_detector",
                                f"robot {detector} (fenced) on robot {notice.robot}")
        return False
    service.fence_life(notice.robot, notice.incarnation)
    if policy == "vanish":
        service.world.vanish(notice.robot)
    return True


def watch_deaths(bus: Bus, service: HwService, policy: DeadBodies) -> None:
    """Subscribe to every robot's death notices (re-announced by the agents)."""
    def handle(_key: str, notice: DeathNotice) -> None:
        on_death(service, notice, policy)

    bus.subscribe(keys.all_deaths(service.mission), DeathNotice, handle, BoundedFifo(4096))
