"""The wire schema table (bus.messages.schema): every kind has an example here that
round-trips strictly through the codec and travels on keys that parse back to its family;
QoS and key families are derived from the table alone."""

from __future__ import annotations

from typing import Any

import msgpack
import numpy as np
import pytest
import zenoh

from bus import codec, keys, qos
from bus.codec import decode, decode_any, encode
from bus.errors import DecodeError, KeyExprError
from bus.messages import (
    MESSAGE_TYPES,
    SCHEMA_VERSION,
    AdminCommand,
    AdminReply,
    AgentState,
    BumpEvent,
    CoverEvent,
    DeathNotice,
    GroundTruthPose,
    Heartbeat,
    HwCommand,
    HwReply,
    LookStep,
    MissionStatus,
    OrmstcClaim,
    OrmstcCompletion,
    OrmstcConnection,
    OrmstcDeadRobot,
    OrmstcRetraction,
    OrmstcStart,
    OrmstcTreeEdge,
    OrmstcWithdrawal,
    PlanShare,
    Progress,
    RadioStats,
    ReplanReport,
    ReplanShare,
    RobotEvent,
    RobotStatus,
    RobotTruth,
    SonarRays,
    TreeReport,
    join_moves,
    make_world_state,
    pack_covered,
    pack_moves,
    pack_routes,
)
from bus.messages.schema import (
    ALIVE,
    FAMILIES,
    INCARNATION,
    KINDS,
    ROBOT,
    KeyFamily,
    Kind,
    QosClass,
    _disjoint,
    family,
)

# One example of every kind in the table; a new row needs one here (see the first test).
EXAMPLES: dict[type[Any], Any] = {ex.__class__: ex for ex in (
    Heartbeat(3, 2, 7, (1, 2, 3), "covering", 1.5, 4, ((0, 1, 2),)),
    RobotStatus(3, 2, (4, 5), "opt", "abc", "covering", "hi"),
    RobotEvent(3, 2, "takeover_started", 1, "walking"),
    DeathNotice(1, 0, 3, "token", 12.5),
    MissionStatus("complete", "done", {"a": 1, "b": 2.5, "c": "x"}),
    Progress(3, 2, 9, (4, 6), 3.25),
    LookStep(3, 2, 1, (6, 7)),
    SonarRays(3, 2, ((4, 5, 1, 3), (4, 5, 0, 8))),
    AgentState(3, 2, "covering", 10, 16, pack_covered(np.arange(16) < 5), (1,), (1,),
               {"hb.decode": 2}, (((0, 0), (0, 1)),), ((1, 1),), "dfs", 4),
    ReplanReport(3, 2, (1, 4), 7, (8, 9, 10), pack_covered(np.arange(16) < 8), 12.5),
    ReplanShare(0, 2, (1, 4), "ab" * 32, (0, 2, 3), (2, 0, 1), pack_routes([[5, 6], [], [9]])),
    PlanShare(0, 2, "cd" * 32, "ab" * 32, (0, 0), pack_moves([(0, 0), (0, 1), (1, 1), (1, 0)]),
              (1, 0), join_moves([[(0, 0), (0, 1)], [(1, 1)]]), (0, 0), ("ccw3", ""),
              ("balanced: a note",), ""),
    HwCommand(11, 3, 2, "sense", ("front", "left")),
    HwReply(11, 3, "ok", "", (1, 2, 0), (0.5, 0.25), {"front": 3, "left": None}, False, 4.0),
    AdminCommand("fail", 3, 40),
    AdminReply(True, "ok", {"n": 1}),
    GroundTruthPose(3, (1, 2, 1), 5.0),
    CoverEvent(3, (2, 2), 5.5, 2),
    BumpEvent(3, (1, 1), (1, 2), 6.0),
    make_world_state("office", np.ones((4, 6), bool), np.arange(24).reshape(4, 6),
                     (RobotTruth(3, (0, 0, 1), True, False, False, 5),), 7.0, 1.0),
    OrmstcStart(3, 2, 1, (0, 1)),
    OrmstcClaim(3, 2, 2, (0, 1), 4),
    OrmstcTreeEdge(3, 2, 3, (0, 0), (0, 1)),
    OrmstcConnection(3, 2, 4, 1, (0, 1), (1, 1)),
    OrmstcDeadRobot(3, 2, 5, 1),
    OrmstcCompletion(3, 2, 6, 9),
    OrmstcWithdrawal(3, 2, 7, 1),
    OrmstcRetraction(3, 2, 8, (0, 0), (0, 1)),
    TreeReport(3, 2, 5, 7, 4, ((1, 2),), (1,)),
    RadioStats(1, 2, 3, 4, 5, 6),
)}


def _id(kind: Kind) -> str:
    return kind.name


def test_every_kind_of_the_table_has_an_example_and_nothing_else_is_registered() -> None:
    listed = [kind.type for kind in KINDS]
    assert len(listed) == len(set(listed))
    missing = [t.__name__ for t in listed if t not in EXAMPLES]
    assert not missing, f"add an example to EXAMPLES for {missing}"
    assert set(EXAMPLES) == set(listed) == set(MESSAGE_TYPES.values())
    assert {kind.name: kind.type for kind in KINDS} == MESSAGE_TYPES


@pytest.mark.parametrize("kind", KINDS, ids=_id)
def test_the_example_of_each_kind_round_trips_strictly(kind: Kind) -> None:
    example = EXAMPLES[kind.type]
    payload = encode(example)
    assert decode(payload, kind.type) == example
    assert decode_any(payload) == example
    assert encode(decode(payload, kind.type)) == payload  # one wire form per message
    raw = msgpack.unpackb(payload, raw=False)
    assert raw[codec.KIND_FIELD] == kind.name and raw[codec.VERSION_FIELD] == SCHEMA_VERSION
    other = next(k.type for k in KINDS if k is not kind)
    with pytest.raises(DecodeError, match="kind"):
        decode(payload, other)


@pytest.mark.parametrize("kind", KINDS, ids=_id)
def test_each_kind_is_read_from_its_generation_on_and_refused_before(kind: Kind) -> None:
    raw = msgpack.unpackb(encode(EXAMPLES[kind.type]), raw=False)
    for version in range(1, SCHEMA_VERSION + 1):
        payload = msgpack.packb({**raw, codec.VERSION_FIELD: version}, use_bin_type=True)
        if version >= kind.since:
            assert decode(payload, kind.type) == EXAMPLES[kind.type]
        else:
            with pytest.raises(DecodeError, match=f"changed in version {kind.since}"):
                decode(payload, kind.type)


def _concrete(fam: KeyFamily, mission: str = "m") -> str:
    return keys.build(fam.label, mission, 3 if ROBOT in fam.chunks else None,
                      5 if INCARNATION in fam.chunks else None)


@pytest.mark.parametrize("kind", KINDS, ids=_id)
def test_each_kind_travels_on_keys_that_parse_back_to_its_family(kind: Kind) -> None:
    assert kind.keys
    for fam in kind.keys:
        key = _concrete(fam)
        parsed = keys.parse(key)
        assert parsed == keys.ParsedKey("m", fam.label, 3 if ROBOT in fam.chunks else None,
                                        5 if INCARNATION in fam.chunks else None)
        assert keys.kind_of(key) == fam.label
        assert zenoh.KeyExpr(keys.wildcard(fam.label, "m")).intersects(zenoh.KeyExpr(key))


def test_each_family_wildcard_matches_its_family_only() -> None:
    """Zenoh's matcher is the oracle; the one overlap is on purpose: a late joiner's query of
    every robot's state also reaches the mission status holder."""
    assert ALIVE in FAMILIES
    assert len({fam.label for fam in FAMILIES}) == len(FAMILIES)
    for fam in FAMILIES:
        pattern = zenoh.KeyExpr(keys.wildcard(fam.label, "m"))
        for other in FAMILIES:
            expected = other is fam or (fam.label, other.label) == ("state", "state/mission")
            assert pattern.intersects(zenoh.KeyExpr(_concrete(other))) == expected, (
                fam.path, other.path)


@pytest.mark.parametrize("kind", KINDS, ids=_id)
def test_qos_comes_from_the_table(kind: Kind) -> None:
    assert qos.qos_for(kind.type) is qos.BY_CLASS[kind.qos]


def test_every_qos_class_has_zenoh_settings() -> None:
    assert set(qos.BY_CLASS) == set(QosClass)
    assert qos.BY_CLASS[QosClass.CRITICAL] is qos.CRITICAL
    assert qos.qos_for(int) is qos.DEFAULT


def test_recoverable_families_are_those_with_a_cache_and_state_that_matters() -> None:
    from bus.messages.schema import FAMILIES, RECOVERABLE

    assert {f.label: f.cache for f in FAMILIES if f.cache} == RECOVERABLE
    # starts, plan digests, progress and cover events, edges, claims, completions, deaths
    for label in ("status", "progress", "sim/cover", "look", "event", "death", "mission",
                  "ormstc/tree", "ormstc/claim", "ormstc/start", "ormstc/done"):
        assert RECOVERABLE[label] > 0, label
    # superseded at once, or not samples at all
    for label in ("hb", "sim/pose", "sim/world", "state", "hw/cmd", "alive"):
        assert label not in RECOVERABLE, label


def test_family_labels_drop_the_id_chunks_unless_given() -> None:
    assert family("hw/{robot}/cmd") == KeyFamily("hw/cmd", "hw/{robot}/cmd")
    assert family("tree/robot/{robot}/inbox", "tree/inbox").label == "tree/inbox"
    # the schema's import-time check that no key is of two families
    assert _disjoint(family("state/{robot}"), family("state/mission"))
    assert _disjoint(family("hw/{robot}/cmd"), family("hw/admin"))
    assert not _disjoint(family("a/{robot}"), family("a/{incarnation}", "b"))


def test_build_needs_exactly_the_family_ids() -> None:
    assert keys.build("hb", "m", 3) == keys.heartbeat("m", 3) == "mstc/m/hb/3"
    assert keys.build("alive", "m", 3, 5) == "mstc/m/alive/3/5"
    assert keys.wildcard("tree/inbox", "m") == "mstc/m/tree/robot/*/inbox"
    for label, robot, incarnation in (("hb", None, None), ("hb", 3, 5), ("mission", 3, None),
                                      ("alive", 3, None)):
        with pytest.raises(KeyExprError, match="ids"):
            keys.build(label, "m", robot, incarnation)
    with pytest.raises(KeyExprError, match="unknown key family"):
        keys.build("nope", "m", 3)
    with pytest.raises(KeyExprError, match="unknown key family"):
        keys.wildcard("nope", "m")
