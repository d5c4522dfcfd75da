"""Codec: every registered message round-trips; every strict-decoding rule rejects."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any, Literal, Union, get_args, get_origin

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bus import codec
from bus.codec import decode, decode_any, encode
from bus.errors import DecodeError, EncodeError
from bus.messages import (
    KIND_SINCE,
    MESSAGE_TYPES,
    NO_ROBOT,
    RECORD_TYPES,
    SCHEMA_VERSION,
    AgentState,
    Heartbeat,
    HwReply,
    Progress,
    ReplanReport,
    RobotEvent,
    RobotTruth,
    WorldState,
    make_world_state,
    world_crossed,
    world_first,
    world_free,
    world_visits,
)


def strategy_for(tp: Any) -> st.SearchStrategy[Any]:
    """Values of a field type, from the type itself (so new messages are covered for free)."""
    origin = get_origin(tp)
    if origin is Literal:
        return st.sampled_from(get_args(tp))
    if origin is Union or origin is types.UnionType:
        return st.one_of([strategy_for(a) for a in get_args(tp)])
    if origin is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return st.lists(strategy_for(args[0]), max_size=4).map(tuple)
        return st.tuples(*[strategy_for(a) for a in args])
    if origin is dict:
        key_tp, value_tp = get_args(tp)
        return st.dictionaries(strategy_for(key_tp), strategy_for(value_tp), max_size=4)
    if tp in RECORD_TYPES:
        return st_message(tp)
    simple: dict[Any, st.SearchStrategy[Any]] = {
        int: st.integers(-(2**63), 2**64 - 1),
        float: st.floats(allow_nan=False),
        str: st.text(max_size=20),
        bytes: st.binary(max_size=20),
        bool: st.booleans(),
        type(None): st.none(),
    }
    return simple[tp]


def st_message(cls: type[Any]) -> st.SearchStrategy[Any]:
    hints = typing.get_type_hints(cls)
    return st.builds(cls, **{f.name: strategy_for(hints[f.name])
                             for f in dataclasses.fields(cls)})


ALL_MESSAGES = st.sampled_from(sorted(MESSAGE_TYPES.values(), key=lambda c: c.KIND)).flatmap(
    st_message)


@settings(max_examples=300, deadline=None)
@given(ALL_MESSAGES)
def test_every_message_round_trips(msg: Any) -> None:
    payload = encode(msg)
    assert decode(payload, type(msg)) == msg
    assert decode_any(payload) == msg
    raw = msgpack.unpackb(payload)
    assert raw[codec.KIND_FIELD] == type(msg).KIND
    assert raw[codec.VERSION_FIELD] == SCHEMA_VERSION


def test_every_registered_type_is_exercised() -> None:
    # The round-trip strategy samples from the registry: check it is what we think it is.
    expected = {"heartbeat", "status", "progress", "event", "death", "mission", "hw_cmd",
                "hw_reply", "admin_cmd", "admin_reply", "gt_pose", "cover", "bump", "world"}
    assert expected <= set(MESSAGE_TYPES)


HB = Heartbeat(robot=1, incarnation=2, seq=3, pose=(4, 5, 1), state="covering", sim_time=1.5,
               said=9, heard=((0, 1, 4), (2, 1, 7)))


def raw_of(msg: Any) -> dict[str, Any]:
    raw: dict[str, Any] = msgpack.unpackb(encode(msg))
    return raw


def pack(raw: Any) -> bytes:
    data: bytes = msgpack.packb(raw, use_bin_type=True)
    return data


def test_a_heartbeat_with_loss_repair_fields_round_trips() -> None:
    assert decode(encode(HB), Heartbeat) == HB
    plain = Heartbeat(1, 2, 3, None, "covering", 1.5)  # other algorithms: 0 and ()
    assert decode(encode(plain), Heartbeat) == plain and plain.said == 0 and plain.heard == ()


@pytest.mark.parametrize(("mutate", "match"), [
    (lambda r: r.update({codec.KIND_FIELD: "progress"}), "kind"),
    (lambda r: r.pop(codec.KIND_FIELD), "kind"),
    (lambda r: r.update({codec.VERSION_FIELD: SCHEMA_VERSION + 1}), "version"),
    (lambda r: r.update({codec.VERSION_FIELD: 0}), "version"),
    (lambda r: r.update({codec.VERSION_FIELD: "1"}), "version"),
    (lambda r: r.pop(codec.VERSION_FIELD), "version"),
    (lambda r: r.pop("seq"), "missing"),
    (lambda r: r.update({"extra": 1}), "extra"),
    (lambda r: r.update({"seq": "3"}), "seq"),
    (lambda r: r.update({"seq": True}), "seq"),
    (lambda r: r.update({"seq": 1.5}), "seq"),
    (lambda r: r.update({"state": None}), "state"),
    (lambda r: r.update({"pose": [1, 2]}), "pose"),
    (lambda r: r.update({"pose": [1, 2, "x"]}), "pose"),
    (lambda r: r.update({"sim_time": "soon"}), "sim_time"),
    (lambda r: r.pop("said"), "missing"),
    (lambda r: r.update({"said": -1.5}), "said"),
    (lambda r: r.update({"heard": [[0, 1]]}), "heard"),
    (lambda r: r.update({"heard": [[0, 1, "4"]]}), "heard"),
])
def test_strict_decoding_rejects(mutate: Any, match: str) -> None:
    raw = raw_of(HB)
    mutate(raw)
    with pytest.raises(DecodeError, match=match):
        decode(pack(raw), Heartbeat)


@pytest.mark.parametrize(("heard", "match"), [
    ([[0, 1, 2], [3, 4, True]], r"heard\[1\]: expected int, got bool"),
    ([[0, 1, 2], [3, 4]], r"heard\[1\]: expected 3 items, got 2"),
    ([[0, 1, 2], [3, 4, 5, 6]], r"heard\[1\]: expected 3 items, got 4"),
    ([[0, 1, 2], [3, 4.0, 5]], r"heard\[1\]: expected int, got float"),
    ([[0, 1, 2], 7], r"heard\[1\]: expected array, got int"),
    ([[0, 1, 2], {"a": 1}], r"heard\[1\]: expected array, got dict"),
    ({"a": 1}, r"heard: expected array, got dict"),
])
def test_a_long_array_of_rows_is_checked_as_strictly_as_item_by_item(heard: Any,
                                                                   match: str) -> None:
    """The arrays of exact scalars and of rows of them (a status's roster, a route, the
    heard list) have a fast check; a value that fails it gets the item-by-item error."""
    raw = raw_of(HB)
    raw["heard"] = heard
    with pytest.raises(DecodeError, match=match):
        decode(pack(raw), Heartbeat)
    raw["heard"] = [[0, 1, 2], [3, 4, 5]]
    assert decode(pack(raw), Heartbeat).heard == ((0, 1, 2), (3, 4, 5))


def test_an_array_of_scalars_is_checked_as_strictly_as_item_by_item() -> None:
    raw = raw_of(ReplanReport(3, 2, (1, 4), 7, (8, 9, 10), b"x", 1.5))
    for bad, match in (([8, True], r"route\[1\]: expected int, got bool"),
                       ([8, 9.0], r"route\[1\]: expected int, got float"),
                       ([8, [9]], r"route\[1\]: expected int, got tuple")):
        raw["route"] = bad
        with pytest.raises(DecodeError, match=match):
            decode(pack(raw), ReplanReport)
    with pytest.raises(EncodeError, match=r"route\[0\]: expected int, got bool"):
        encode(ReplanReport(3, 2, (1, 4), 7, (True,), b"x", 1.5))
    raw["route"] = list(range(500))
    assert decode(pack(raw), ReplanReport).route == tuple(range(500))


def test_a_kind_is_read_from_every_generation_since_its_last_change() -> None:
    """Progress is unchanged since generation 1: payloads of generations 1..now decode; a
    kind listed with since = g refuses older payloads and says why."""
    sent = Progress(robot=1, incarnation=0, seq=3, cell=(2, 4), sim_time=1.5)
    raw = msgpack.unpackb(encode(sent), raw=False)
    for version in range(1, SCHEMA_VERSION + 1):
        assert decode(pack(dict(raw, _v=version)), Progress) == sent
    assert KIND_SINCE["agent_state"] == 2
    state = AgentState(robot=0, incarnation=0, state="done", moves=1, n=0, covered=b"",
                       dead=(), took_over=())
    old = dict(msgpack.unpackb(encode(state), raw=False), _v=1)
    with pytest.raises(DecodeError, match="changed in version 2"):
        decode(pack(old), AgentState)


def test_literal_and_nested_records_are_checked() -> None:
    raw = raw_of(RobotEvent(robot=1, incarnation=1, kind="leaving"))
    raw["kind"] = "exploded"
    with pytest.raises(DecodeError, match="kind"):
        decode(pack(raw), RobotEvent)
    world = make_world_state("m", np.ones((2, 3), bool), np.zeros((2, 3), int),
                             (RobotTruth(0, (0, 0, 0), True, False, False, 0),), 0.0, 1.0)
    raw = raw_of(world)
    raw["robots"][0]["alive"] = 1
    with pytest.raises(DecodeError, match="alive"):
        decode(pack(raw), WorldState)


def test_float_fields_accept_ints_from_other_languages() -> None:
    raw = raw_of(HB)
    raw["sim_time"] = 2
    assert decode(pack(raw), Heartbeat).sim_time == 2.0


@pytest.mark.parametrize("payload", [b"", b"\xc1", b"\x93\x01\x02\x03", pack("text"),
                                     pack({1: 2})])
def test_non_messages_are_rejected(payload: bytes) -> None:
    with pytest.raises(DecodeError):
        decode(payload, Heartbeat)


def test_oversized_payload_is_rejected_before_parsing() -> None:
    big = Progress(robot=1, incarnation=1, seq=1, cell=(0, 0), sim_time=0.0)
    payload = encode(big)
    with pytest.raises(DecodeError, match="exceeds"):
        decode(payload, Progress, max_size=len(payload) - 1)
    assert decode(payload, Progress, max_size=len(payload)) == big
    with pytest.raises(DecodeError, match="exceeds"):
        decode(b"\x00" * (codec.DEFAULT_MAX_PAYLOAD + 1), Progress)


def test_tuple_of_expected_types_selects_by_kind() -> None:
    prog = Progress(robot=1, incarnation=1, seq=1, cell=(0, 0), sim_time=0.0)
    assert decode(encode(prog), (Heartbeat, Progress)) == prog
    with pytest.raises(DecodeError, match="kind"):
        decode(encode(prog), (Heartbeat, RobotEvent))


def test_encode_rejects_bad_fields_and_unregistered_types() -> None:
    with pytest.raises(EncodeError, match="seq"):
        encode(dataclasses.replace(HB, seq="3"))  # type: ignore[arg-type]
    with pytest.raises(EncodeError, match="status"):
        encode(HwReply(1, 1, "exploded", "", (0, 0, 0), (0.0, 0.0), {}, False,  # type: ignore[arg-type]
                       0.0))

    @dataclasses.dataclass(frozen=True)
    class Stranger:
        KIND = "stranger"
        x: int

    with pytest.raises(EncodeError, match="registered"):
        encode(Stranger(1))
    with pytest.raises(EncodeError, match="exceeds"):
        encode(HB, max_size=8)


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 40), st.integers(1, 40), st.data())
def test_world_state_packs_masks_exactly(h: int, w: int, data: st.DataObject) -> None:
    free = np.array(data.draw(st.lists(st.booleans(), min_size=h * w, max_size=h * w)),
                    dtype=bool).reshape(h, w)
    visits = np.array(data.draw(st.lists(st.integers(0, 1000), min_size=h * w,
                                         max_size=h * w))).reshape(h, w)
    state = decode(encode(make_world_state("m", free, visits, (), 1.0, 2.0)), WorldState)
    assert np.array_equal(world_free(state), free)
    assert np.array_equal(world_visits(state), np.minimum(visits, 255))


def test_world_state_packs_first_visitors_and_crossers_losslessly() -> None:
    rng = np.random.default_rng(5)
    free = rng.random((6, 8)) < 0.8
    visits = rng.integers(0, 300, (6, 8))
    first = rng.integers(0, 256, (6, 8)).astype(np.uint8)
    right = rng.integers(0, 256, (3, 3)).astype(np.uint8)
    down = rng.integers(0, 256, (2, 4)).astype(np.uint8)
    state = decode(encode(make_world_state("m", free, visits, (), 1.0, 0.0, first=first,
                                           crossed=(right, down))), WorldState)
    assert np.array_equal(world_free(state), free)
    assert np.array_equal(world_visits(state), np.minimum(visits, 255))
    assert np.array_equal(world_first(state), first)
    got_right, got_down = world_crossed(state)
    assert np.array_equal(got_right, right) and np.array_equal(got_down, down)
    empty = make_world_state("m", free, visits, (), 1.0, 0.0)
    assert (world_first(empty) == NO_ROBOT).all()
    assert all((a == NO_ROBOT).all() for a in world_crossed(empty))
    with pytest.raises(ValueError, match="shape"):
        make_world_state("m", free, visits, (), 1.0, 0.0, first=first[:, :4])
    with pytest.raises(ValueError, match="decompress"):
        world_first(dataclasses.replace(state, first=b"not zlib"))
    with pytest.raises(ValueError, match="expected"):
        world_first(dataclasses.replace(state, first=state.visits[:0] + state.crossed))


def test_world_state_of_the_largest_benchmark_maps_fits_one_payload() -> None:
    """107 x 107 sub-cells with incompressible (random) visits and first visitors: the
    worst case for the 64 KiB limit; real missions compress far better."""
    rng = np.random.default_rng(0)
    shape = (107, 107)
    robots = tuple(RobotTruth(r, (0, 0, 0), True, False, False, 100) for r in range(64))
    state = make_world_state(
        "big", rng.random(shape) < 0.7, rng.integers(0, 256, shape), robots, 1.0, 0.0,
        first=rng.integers(0, 255, shape).astype(np.uint8),
        crossed=(rng.integers(0, 255, (53, 52)).astype(np.uint8),
                 rng.integers(0, 255, (52, 53)).astype(np.uint8)))
    assert decode(encode(state), WorldState) == state


def test_agent_state_of_one_robot_owning_a_whole_benchmark_map_fits_one_payload() -> None:
    """An ORMSTC robot alone on 53 x 53 cells owns all of them: 2808 tree edges."""
    tree = tuple(((r, c), (r, c + 1)) for r in range(53) for c in range(52)) \
        + tuple(((r, 0), (r + 1, 0)) for r in range(52))
    claims = tuple((r, c) for r in range(10) for c in range(10))
    st_ = AgentState(0, 3, "covering", 10_000, 0, b"", (1, 2), (), {"x.y": 1}, tree, claims)
    assert len(tree) == 53 * 53 - 1
    assert decode(encode(st_), AgentState) == st_
