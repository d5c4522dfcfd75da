"""Wire messages of connected tree coverage in the fleet (NCOCTA / COCTA, docs/treecover.md).

Nodes are the tree's node ids (0 is the root); ``step`` counts synchronous steps from 0 (all
robots on the root).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar


@dataclass(frozen=True)
class TreeReport:
    """Robot ``robot`` stands on ``node`` at ``step``. ``sender`` is the robot transmitting
    this copy: ``robot`` itself for its own report, another robot when relaying it (the radio
    reaches only robots on the same or an adjacent node, so reports travel hop by hop).

    ``gone``: (robot, step) for every robot ``robot``'s team replica removed before ``step``
    (dead; removed at that step's boundary; ascending); every report of one step must carry
    the same, or the replicas have diverged.
    ``dead``: the robots ``robot`` knew dead when it reported (ascending), passed on so that
    knowledge of a death spreads with the reports (schema 3)."""

    KIND: ClassVar[str] = "tree_report"
    robot: int
    incarnation: int
    step: int
    node: int
    sender: int
    gone: tuple[tuple[int, int], ...] = ()
    dead: tuple[int, ...] = ()


@dataclass(frozen=True)
class RadioStats:
    """The radio relay's counters, the reply of its ``tree/radio`` queryable.

    ``transmissions`` copies received on outboxes; ``deliveries`` copies put on inboxes;
    ``refused`` (copy, robot) pairs not delivered because the robot was out of range;
    ``pending`` pairs held until the robot reports where it stands at that step;
    ``unlocated`` transmissions from a robot whose node at that step was unknown (dropped);
    ``spoofed`` copies whose ``sender`` was not the outbox's robot (dropped)."""

    KIND: ClassVar[str] = "radio_stats"
    transmissions: int
    deliveries: int
    refused: int
    pending: int
    unlocated: int
    spoofed: int
