"""Quality of service: what each QoS class of the wire schema means to Zenoh.

Which class a kind has is its row in bus.messages.schema. Heartbeats get a priority of their
own (INTERACTIVE_HIGH) so that a burst of data cannot queue behind them or delay them into a
false suspicion. Events, death notices and mission status are small and must not be lost to a
full queue, so they BLOCK (at most Zenoh's 5 s before the transport is closed); streams whose
newest value supersedes the old one (poses, progress, ground truth) DROP under congestion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import zenoh

from bus.messages.schema import KINDS, QosClass


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

BY_CLASS: dict[QosClass, Qos] = {
    QosClass.HEARTBEAT: HEARTBEAT,
    QosClass.CRITICAL: CRITICAL,
    QosClass.CONTROL: CONTROL,
    QosClass.STREAM: STREAM,
    QosClass.BULK: BULK,
}

_BY_TYPE: dict[type[Any], Qos] = {kind.type: BY_CLASS[kind.qos] for kind in KINDS}


def qos_for(msg_type: type[Any]) -> Qos:
    """The default QoS of a message type (STREAM for types not in the schema)."""
    return _BY_TYPE.get(msg_type, DEFAULT)
