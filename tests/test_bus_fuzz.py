"""Property-based fuzzing of every decoder and key parser: whatever arrives (random bytes,
truncated or mutated valid messages, huge or deeply nested msgpack) nothing but the codec's
own DecodeError leaves the codec, oversized payloads are refused before decoding, and the bus
counts every drop. Second-level decoders (packed arrays inside messages) raise ValueError
only, and never allocate more than their message could hold."""

from __future__ import annotations

import contextlib
from typing import Any, cast

import msgpack
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_bus_schema import EXAMPLES

from bus import codec, keys
from bus.bridge import Bus
from bus.codec import decode, decode_any, encode
from bus.detector import FailureDetector
from bus.errors import DecodeError
from bus.messages import (
    DeathNotice,
    unpack_covered,
    world_crossed,
    world_first,
    world_free,
    world_visits,
)
from bus.messages.schema import ALIVE, FAMILIES, KINDS, MESSAGE_TYPES

FUZZ = settings(max_examples=300, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])
PAYLOADS = [encode(example) for example in EXAMPLES.values()]
TYPES = tuple(MESSAGE_TYPES.values())

# msgpack values of every shape the wire can carry
values = st.recursive(
    st.none() | st.booleans() | st.integers(-2**64, 2**64 - 1) | st.floats()
    | st.text(max_size=20) | st.binary(max_size=20),
    lambda inner: st.lists(inner, max_size=5)
    | st.dictionaries(st.text(max_size=8) | st.integers(), inner, max_size=5),
    max_leaves=30)


def _decodes_or_refuses(payload: bytes) -> None:
    every: tuple[Any, ...] = (TYPES, *TYPES)
    for expected in every:
        with contextlib.suppress(DecodeError):
            decode(payload, expected)


def _packable(value: Any) -> bytes | None:
    try:
        packed: bytes = msgpack.packb(value, use_bin_type=True)
    except (OverflowError, ValueError, TypeError):
        return None
    return packed


@FUZZ
@given(st.binary(max_size=4096))
def test_random_bytes_never_raise_out_of_the_codec(payload: bytes) -> None:
    _decodes_or_refuses(payload)


@FUZZ
@given(st.sampled_from(PAYLOADS), st.data())
def test_truncated_and_mutated_messages_never_raise(payload: bytes, data: st.DataObject) -> None:
    cut = data.draw(st.integers(0, len(payload)))
    _decodes_or_refuses(payload[:cut])
    mutated = bytearray(payload)
    for _ in range(data.draw(st.integers(1, 8))):
        at = data.draw(st.integers(0, len(mutated) - 1))
        mutated[at] = data.draw(st.integers(0, 255))
    _decodes_or_refuses(bytes(mutated))
    at = data.draw(st.integers(0, len(payload)))
    _decodes_or_refuses(payload[:at] + data.draw(st.binary(max_size=16)) + payload[at:])


@FUZZ
@given(st.sampled_from(PAYLOADS), st.data())
def test_valid_envelopes_with_fields_of_any_shape_never_raise(
        payload: bytes, data: st.DataObject) -> None:
    raw = dict(msgpack.unpackb(payload, raw=False))
    names = sorted(raw)
    for _ in range(data.draw(st.integers(1, 3))):
        action = data.draw(st.sampled_from(["set", "drop", "add"]))
        if action == "set":
            raw[data.draw(st.sampled_from(names))] = data.draw(values)
        elif action == "drop":
            raw.pop(data.draw(st.sampled_from(names)), None)
        else:
            raw[data.draw(st.text(max_size=8) | st.integers())] = data.draw(values)
    packed = _packable(raw)
    assume(packed is not None)
    assert packed is not None
    _decodes_or_refuses(packed)


@FUZZ
@given(values)
def test_any_msgpack_value_never_raises(value: Any) -> None:
    packed = _packable(value)
    assume(packed is not None)
    assert packed is not None
    _decodes_or_refuses(packed)


@pytest.mark.parametrize("depth", [10, 1000, 100_000])
@pytest.mark.parametrize("opener", [b"\x91", b"\x81\xa1k"])
def test_deeply_nested_msgpack_is_refused(depth: int, opener: bytes) -> None:
    payload = opener * depth + b"\xc0"
    with pytest.raises(DecodeError):
        decode_any(payload, max_size=len(payload))
    inner: Any = 1
    for _ in range(min(depth, 200)):
        inner = {"k": [inner]}
    nested = encode_raw({**_raw_of(PAYLOADS[0]), "pose": inner})
    with pytest.raises(DecodeError):
        decode_any(nested)


def encode_raw(raw: dict[str, Any]) -> bytes:
    packed: bytes = msgpack.packb(raw, use_bin_type=True)
    return packed


def _raw_of(payload: bytes) -> dict[str, Any]:
    return dict(msgpack.unpackb(payload, raw=False))


@pytest.mark.parametrize("header", [b"\xdd\xff\xff\xff\xff", b"\xdf\xff\xff\xff\xff",
                                    b"\xc6\xff\xff\xff\xff", b"\xdb\xff\xff\xff\xff"])
def test_huge_declared_lengths_are_refused_without_allocating(header: bytes) -> None:
    with pytest.raises(DecodeError):
        decode_any(header + b"\x00" * 16)


def test_oversized_payloads_are_refused_before_decoding(monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(*_args: Any, **_kwargs: Any) -> Any:
        raise AssertionError("msgpack was asked to decode an oversized payload")

    monkeypatch.setattr(codec.msgpack, "unpackb", boom)
    with pytest.raises(DecodeError, match="exceeds"):
        decode_any(b"\x90" * (codec.DEFAULT_MAX_PAYLOAD + 1))
    with pytest.raises(DecodeError, match="exceeds"):
        decode_any(PAYLOADS[0], max_size=len(PAYLOADS[0]) - 1)


@FUZZ
@given(st.binary(max_size=512), st.text(max_size=60))
def test_the_bus_counts_every_drop_and_never_raises(payload: bytes, key: str) -> None:
    bus = Bus(cast(Any, None), "m")
    before = bus.drops.total()
    msg = bus.decode_or_count(key, payload, TYPES)
    assert (msg is None) == (bus.drops.total() == before + 1)


@FUZZ
@given(st.text(max_size=80) | st.lists(
    st.sampled_from(["mstc", "m", "hb", "alive", "ormstc", "tree", "robot", "inbox", "hw",
                     "cmd", "state", "*", "**", "", "0", "3", "-1", "٣", "9" * 5000]),
    max_size=7).map("/".join))
def test_key_parsing_never_raises(key: str) -> None:
    parsed = keys.parse(key)
    label = keys.kind_of(key)
    if parsed is None:
        assert label == "foreign"
    else:
        assert label == parsed.kind
        assert keys.build(parsed.kind, parsed.mission, parsed.robot, parsed.incarnation) == key


@given(st.integers(0, 10**6), st.integers(0, 10**6))
def test_every_built_key_parses_back(robot: int, incarnation: int) -> None:
    for fam in (*FAMILIES, ALIVE):
        ids = {"robot": robot if "{robot}" in fam.chunks else None,
               "incarnation": incarnation if "{incarnation}" in fam.chunks else None}
        key = keys.build(fam.label, "m", **ids)
        assert keys.parse(key) == keys.ParsedKey("m", fam.label, ids["robot"],
                                                 ids["incarnation"])


@FUZZ
@given(st.binary(max_size=256), st.integers(-5, 10**12))
def test_packed_coverage_raises_value_error_only(data: bytes, n: int) -> None:
    try:
        bits = unpack_covered(data, n)
    except ValueError:
        return
    assert bits.size == n and n <= len(data) * 8 * 1032  # zlib's best ratio bounds it


@FUZZ
@given(st.data())
def test_packed_world_arrays_raise_value_error_only(data: st.DataObject) -> None:
    world = EXAMPLES[next(k.type for k in KINDS if k.name == "world")]
    shape = data.draw(st.tuples(st.integers(-3, 10**6), st.integers(-3, 10**6)))
    fields = {name: data.draw(st.binary(max_size=64) | st.just(getattr(world, name)))
              for name in ("free", "visits", "first", "crossed")}
    state = type(world)(**{**world.__dict__, **fields, "shape": shape})
    for unpack in (world_free, world_visits, world_first, world_crossed):
        try:
            unpack(state)
        except ValueError:
            continue


@FUZZ
@given(st.builds(DeathNotice, st.integers(-3, 2**63), st.integers(-3, 2**63),
                 st.none() | st.integers(-3, 2**63),
                 st.sampled_from(["token", "heartbeat", "leaving"]), st.floats()))
def test_death_notice_checks_never_raise(notice: DeathNotice) -> None:
    fd = FailureDetector(detector=0)
    fd.on_token(1, 1, 0.0)
    problem = fd.notice_problem(notice)
    assert problem is None or isinstance(problem, str)
