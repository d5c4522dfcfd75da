"""ROS 2's wire format over Zenoh, as rmw_zenoh_cpp writes it: key expressions, liveliness
tokens, QoS strings and the per-sample attachment. Pure: strings and bytes only.

- a topic's data travels on ``<domain>/<topic without its leading slash>/<DDS type
  name>/RIHS01_<hash>``, e.g. ``0/chatter/std_msgs::msg::dds_::String_/RIHS01_df66…``;
- each entity announces itself with a liveliness token ``@ros2_lv/<domain>/<session id>/
  <node id>/<entity id>/<NN|MP|MS|SS|SC>/<enclave>/<namespace>/<node>[/<topic>/<type>/
  <hash>/<qos>]``, where ``/`` inside a name is written ``%`` (an empty or root name is
  ``%``) and the QoS is ``reliability:durability:history,depth:deadline s,ns:lifespan s,ns:
  liveliness,lease s,lease ns`` with every value that equals rmw_zenoh's default left empty;
- a sample's payload is the CDR message with its 4-byte encapsulation header, and its
  attachment is zenoh-ext's serialization of (sequence number int64, source timestamp int64
  in ns, source GID as 16 bytes with a one-byte length): 33 bytes.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass

from deploy.robotics import ros

ADMIN_SPACE = "@ros2_lv"
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
GID_SIZE = 16  # RMW_GID_STORAGE_SIZE since Jazzy
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE

# rmw's enumerations (rmw/types.h)
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
AUTOMATIC = 1
INFINITE_S, INFINITE_NS = 9223372036, 854775807  # RMW_DURATION_INFINITE


@dataclass(frozen=True)
class Qos:
    """A QoS profile; the defaults are rmw_zenoh's, which its key strings leave out."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = 42
    deadline: tuple[int, int] = (INFINITE_S, INFINITE_NS)
    lifespan: tuple[int, int] = (INFINITE_S, INFINITE_NS)
    liveliness: int = AUTOMATIC
    lease: tuple[int, int] = (INFINITE_S, INFINITE_NS)


DEFAULT_QOS = Qos()
LATCHED = Qos(durability=TRANSIENT_LOCAL, depth=1)  # a map: late subscribers get the last one


def dds_type_name(typename: str) -> str:
    """``pkg/msg/Name`` as rmw_zenoh's key names it: ``pkg::msg::dds_::Name_``."""
    package, kind, name = typename.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def type_hash(typename: str) -> str:
    """ROS 2's type description hash, ``RIHS01_`` and 64 hex digits (rosbags computes it
    from the type definitions; no ROS needed)."""
    return ros.typestore().hash_rihs01(typename)


def strip_slashes(name: str) -> str:
    return name[1:] if name.startswith("/") else name


def topic_key(domain: int, topic: str, typename: str) -> str:
    return f"{domain}/{strip_slashes(topic).rstrip('/')}/{dds_type_name(typename)}/" \
           f"{type_hash(typename)}"


def mangle(name: str) -> str:
    return name.replace("/", "%") if name else "%"


def _field(value: object, default: object) -> str:
    return "" if value == default else str(value)


def qos_key(qos: Qos) -> str:
    d = DEFAULT_QOS
    return ":".join([
        _field(qos.reliability, d.reliability), _field(qos.durability, d.durability),
        f"{_field(qos.history, d.history)},{_field(qos.depth, d.depth)}",
        f"{_field(qos.deadline[0], d.deadline[0])},{_field(qos.deadline[1], d.deadline[1])}",
        f"{_field(qos.lifespan[0], d.lifespan[0])},{_field(qos.lifespan[1], d.lifespan[1])}",
        f"{_field(qos.liveliness, d.liveliness)},{_field(qos.lease[0], d.lease[0])},"
        f"{_field(qos.lease[1], d.lease[1])}"])


@dataclass(frozen=True)
class NodeName:
    domain: int
    zid: str  # the Zenoh session id, as the session prints it
    node_id: int
    namespace: str
    name: str
    enclave: str = "/"

    def prefix(self, entity_id: int, kind: str) -> str:
        return "/".join([ADMIN_SPACE, str(self.domain), self.zid, str(self.node_id),
                         str(entity_id), kind, mangle(self.enclave), mangle(self.namespace),
                         mangle(self.name)])


def node_token(node: NodeName) -> str:
    """The node's own token: its entity id is its node id."""
    return node.prefix(node.node_id, NODE)


def publisher_token(node: NodeName, entity_id: int, topic: str, typename: str,
                    qos: Qos = DEFAULT_QOS) -> str:
    return "/".join([node.prefix(entity_id, PUBLISHER), mangle(topic),
                     mangle(dds_type_name(typename)), mangle(type_hash(typename)),
                     qos_key(qos)])


def gid(token: str) -> bytes:
    """A publisher's 16-byte GID, derived from its token. rmw_zenoh uses XXH3-128 of the
    token; any stable 16 bytes identify a publisher equally well to a subscriber."""
    return hashlib.blake2b(token.encode(), digest_size=GID_SIZE).digest()


def attachment(sequence_number: int, source_timestamp_ns: int, source_gid: bytes) -> bytes:
    """The 33-byte attachment of one sample."""
    if len(source_gid) != GID_SIZE:
        raise ValueError(f"a GID has {GID_SIZE} bytes, got {len(source_gid)}")
    return struct.pack("<qqB", sequence_number, source_timestamp_ns, GID_SIZE) + source_gid


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    if len(data) != ATTACHMENT_SIZE or data[16] != GID_SIZE:
        raise ValueError(f"not an rmw_zenoh attachment ({len(data)} bytes)")
    sequence_number, timestamp = struct.unpack_from("<qq", data)
    return sequence_number, timestamp, bytes(data[17:])
