"""ORMSTC on the wire: every ORMSTC bus message round-trips, strict decoding rejects, the
conversions to and from planner.ormstc's messages are inverse, and a receiver drops what it
must (agent.ormstc.wire.Inbound)."""

from __future__ import annotations

import dataclasses
from typing import Any

import msgpack
import pytest
import zenoh
from hypothesis import given, settings
from hypothesis import strategies as st

from agent.ormstc.wire import WIRE_TYPES, Inbound, from_wire, key_for, to_wire
from bus import keys, qos
from bus.codec import decode, decode_any, encode
from bus.drops import DropCounter
from bus.errors import DecodeError
from bus.messages import ORMSTC_MESSAGES, OrmstcClaim, OrmstcDeadRobot, OrmstcTreeEdge
from planner.ormstc.types import (
    ClaimMsg,
    CompletionMsg,
    ConnectionMsg,
    DeadRobotMsg,
    Message,
    RetractionMsg,
    StartMsg,
    TreeEdgeMsg,
    WithdrawalMsg,
)

ints = st.integers(-(2**31), 2**31)
pairs = st.tuples(ints, ints)
robots = st.integers(0, 50)
planner_messages: st.SearchStrategy[Message] = st.one_of(
    st.builds(StartMsg, robots, pairs), st.builds(ClaimMsg, robots, pairs, ints),
    st.builds(TreeEdgeMsg, robots, pairs, pairs),
    st.builds(ConnectionMsg, robots, robots, pairs, pairs),
    st.builds(DeadRobotMsg, robots, robots), st.builds(CompletionMsg, robots, ints),
    st.builds(WithdrawalMsg, robots, robots))


@settings(max_examples=300, deadline=None)
@given(planner_messages, st.integers(1, 10), st.integers(1, 2**40))
def test_planner_messages_survive_the_wire(msg: Message, incarnation: int, seq: int) -> None:
    wire = to_wire(msg, incarnation, seq)
    assert type(wire) in ORMSTC_MESSAGES
    payload = encode(wire)
    back: Any = decode(payload, WIRE_TYPES)
    assert back == wire and decode_any(payload) == wire
    assert from_wire(back) == msg
    assert (back.robot, back.incarnation, back.seq) == (msg.robot, incarnation, seq)
    key = key_for("m", back)
    parsed = keys.parse(key)
    assert parsed is not None and parsed.robot == msg.robot
    assert zenoh.KeyExpr(keys.all_ormstc("m")).intersects(zenoh.KeyExpr(key))


def test_each_kind_has_its_own_key_and_one_shared_qos() -> None:
    samples = [to_wire(m, 1, 1) for m in (
        StartMsg(3, (0, 1)), ClaimMsg(3, (0, 1), 2), TreeEdgeMsg(3, (0, 0), (0, 1)),
        ConnectionMsg(3, 1, (0, 0), (0, 1)), DeadRobotMsg(3, 1), CompletionMsg(3, 4),
        WithdrawalMsg(3, 1), RetractionMsg(3, (0, 0), (0, 1)))]
    assert {type(s) for s in samples} == set(ORMSTC_MESSAGES)
    built = {key_for("m", s) for s in samples}
    assert len(built) == len(samples)
    for key in built:
        kind = keys.kind_of(key)
        assert kind.startswith("ormstc/")
        assert zenoh.KeyExpr(keys.all_ormstc("m", kind.split("/")[1])).intersects(
            zenoh.KeyExpr(key))
    # FIFO per sender across keys needs one priority and no dropping under congestion
    assert all(qos.qos_for(t) is qos.CRITICAL for t in ORMSTC_MESSAGES)


def _raw(msg: Any) -> dict[str, Any]:
    raw: dict[str, Any] = msgpack.unpackb(encode(msg), raw=False)
    return raw


@pytest.mark.parametrize("cls", ORMSTC_MESSAGES)
def test_strict_decoding_rejects_each_broken_field(cls: type[Any]) -> None:
    examples: dict[str, Message] = {
        "OrmstcStart": StartMsg(1, (2, 3)), "OrmstcClaim": ClaimMsg(1, (2, 3), 4),
        "OrmstcTreeEdge": TreeEdgeMsg(1, (2, 2), (2, 3)),
        "OrmstcConnection": ConnectionMsg(1, 0, (2, 2), (2, 3)),
        "OrmstcDeadRobot": DeadRobotMsg(1, 0), "OrmstcCompletion": CompletionMsg(1, 9),
        "OrmstcWithdrawal": WithdrawalMsg(1, 0),
        "OrmstcRetraction": RetractionMsg(1, (2, 2), (2, 3))}
    wire = to_wire(examples[cls.__name__], 2, 7)
    assert type(wire) is cls
    raw = _raw(wire)
    for field in dataclasses.fields(cls):
        for bad in (True, "x", [1, 2, 3], None):
            broken = {**raw, field.name: bad}
            with pytest.raises(DecodeError):
                decode(msgpack.packb(broken), cls)
        missing = {k: v for k, v in raw.items() if k != field.name}
        with pytest.raises(DecodeError):
            decode(msgpack.packb(missing), cls)
    with pytest.raises(DecodeError):
        decode(msgpack.packb({**raw, "extra": 1}), cls)
    with pytest.raises(DecodeError):
        decode(encode(wire), OrmstcClaim if cls is not OrmstcClaim else OrmstcTreeEdge)


def test_inbound_drops_what_it_must_and_holds_back_after_a_gap() -> None:
    drops = DropCounter()
    inbound = Inbound(me=0, k=3, drops=drops)
    claim = OrmstcClaim(1, 1, 1, (0, 0), 0)
    assert inbound.accept(keys.ormstc_claim("m", 1), claim) == [(claim, ClaimMsg(1, (0, 0), 0))]
    assert inbound.accept(keys.ormstc_claim("m", 2), claim) == []  # key names robot 2
    assert inbound.accept(keys.ormstc_claim("m", 5), OrmstcClaim(5, 1, 1, (0, 0), 0)) == []
    assert inbound.accept(keys.ormstc_claim("m", 0), OrmstcClaim(0, 1, 1, (0, 0), 0)) == []
    dead = OrmstcDeadRobot(1, 1, 2, 9)  # names robot 9, outside the fleet
    assert inbound.accept(keys.ormstc_dead("m", 1), dead) == []
    assert drops.total(reason="invalid") == 3
    # seq 3 and 4 lost: counted, and the edge (5) is held back until they come
    edge = OrmstcTreeEdge(1, 1, 5, (0, 0), (0, 1))
    assert inbound.accept(keys.ormstc_tree("m", 1), edge, now=1.0) == []
    assert inbound.gaps == 2 and drops.total(reason="gap") == 1
    assert inbound.streams.missing(1) == [3, 4]
    assert inbound.streams.horizon(1) == 0.0  # the first claim's arrival
    late = OrmstcClaim(1, 1, 4, (0, 1), 1)
    assert inbound.accept(keys.ormstc_claim("m", 1), late, now=2.0) == []
    resent = OrmstcClaim(1, 1, 3, (0, 2), 1)
    assert [m for _, m in inbound.accept(keys.ormstc_claim("m", 1), resent, now=3.0)] == [
        ClaimMsg(1, (0, 2), 1), ClaimMsg(1, (0, 1), 1), TreeEdgeMsg(1, (0, 0), (0, 1))]
    assert inbound.streams.horizon(1) == 3.0
    assert inbound.accept(keys.ormstc_claim("m", 1), resent, now=4.0) == []  # a duplicate
    assert inbound.streams.duplicates == 1
    # a new life starts its numbering again; the old life is fenced from then on
    assert inbound.accept(keys.ormstc_claim("m", 1), OrmstcClaim(1, 2, 1, (5, 5), 0))
    assert inbound.accept(keys.ormstc_claim("m", 1), OrmstcClaim(1, 1, 5, (5, 5), 0)) == []
    assert drops.total(reason="stale") == 1 and inbound.gaps == 2
