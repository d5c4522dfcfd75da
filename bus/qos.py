"""Quality of service per message kind: priority, congestion control, express.

Heartbeats get a priority of their own (INTERACTIVE_HIGH) so that a burst of data cannot
queue behind them or delay them into a false suspicion. Events, death notices and mission
status are small and must not be lost to a full queue, so they BLOCK (at most Zenoh's 5 s
before the transport is closed); streams whose newest value supersedes the old one (poses,
progress, ground truth) DROP under congestion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import zenoh

from bus import messages as m


@dataclass(frozen=True)
class Qos:
    priority: zenoh.Priority
    congestion: zenoh.CongestionControl
    express: bool = False


HEARTBEAT = Qos(zenoh.Priority.INTERACTIVE_HIGH, zenoh.CongestionControl.DROP, express=True)
CRITICAL = Qos(zenoh.Priority.DATA_HIGH, zenoh.CongestionControl.BLOCK)
CONTROL = Qos(zenoh.Priority.INTERACTIVE_LOW, zenoh.CongestionControl.BLOCK)
STREAM = Qos(zenoh.Priority.DATA, zenoh.CongestionControl.DROP)
BULK = Qos(zenoh.Priority.DATA_LOW, zenoh.CongestionControl.DROP)

DEFAULT = STREAM

_BY_TYPE: dict[type[Any], Qos] = {
    m.Heartbeat: HEARTBEAT,
    m.RobotEvent: CRITICAL,
    m.LookStep: CRITICAL,  # a lost one would make a report see a coverage revisit
    m.DeathNotice: CRITICAL,
    m.MissionStatus: CRITICAL,
    m.RobotStatus: CRITICAL,
    m.HwCommand: CONTROL,
    m.HwReply: CONTROL,
    m.AdminCommand: CONTROL,
    m.AdminReply: CONTROL,
    m.Progress: STREAM,
    m.GroundTruthPose: STREAM,
    m.CoverEvent: STREAM,
    m.BumpEvent: STREAM,
    m.WorldState: BULK,
    # one priority for every ORMSTC kind keeps each sender's messages in order across keys
    **{t: CRITICAL for t in m.ORMSTC_MESSAGES},
    # a lost tree report stalls the whole team's step: never drop it under congestion
    m.TreeReport: CRITICAL,
    m.RadioStats: CONTROL,
}


def qos_for(msg_type: type[Any]) -> Qos:
    """The default QoS of a message type (STREAM for types not listed)."""
    return _BY_TYPE.get(msg_type, STREAM)
