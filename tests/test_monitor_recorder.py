"""Recordings: every message kind survives the JSON round trip; bad lines are reported by
number and skipped; unusable files are one readable error."""

from __future__ import annotations

import json
import math
from pathlib import Path

import msgpack
import pytest
from test_monitor_fixtures import M, open_room, run_mission, two_robot_walks

from bus import keys
from bus.codec import encode
from bus.errors import DecodeError
from bus.messages import (
    SCHEMA_VERSION,
    AdminReply,
    AgentState,
    HwReply,
    MissionStatus,
    RobotTruth,
    make_world_state,
)
from bus.messages.schema import KIND_SINCE
from deploy.monitor.recorder import (
    RecordingError,
    RecordWriter,
    decode_payload,
    parse_line,
    read_recording,
    record_line,
)
from deploy.monitor.types import Gap, Header, Opaque, Record

HEADER = Header(M, 1_700_000_000.0, "test", SCHEMA_VERSION)


def write(path: Path, records: list[Record]) -> None:
    with RecordWriter(path, HEADER) as writer:
        for record in records:
            writer.write(record)


def samples() -> list[Record]:
    """One of each awkward shape: bytes, nested records, dicts, None, non-finite floats."""
    import numpy as np

    world = make_world_state("w", np.ones((3, 5), dtype=bool), np.arange(15).reshape(3, 5),
                             (RobotTruth(0, (1, 2, 3), True, False, False, 4),), 2.5,
                             math.inf)
    return [
        Record(0.5, keys.world(M), world, "query"),
        Record(0.6, keys.hw_cmd(M, 0), HwReply(7, 0, "ok", "", (1, 1, 0), (0.4, 0.0),
                                                {"front": None, "left": 2}, False, 1.0)),
        Record(0.7, keys.hw_admin(M), AdminReply(True, "", {"a": 1, "b": 2.5, "c": "x"})),
        Record(0.8, keys.mission_status(M), MissionStatus("failed", "why", {"n": -1})),
        Record(0.9, keys.state(M, 2), AgentState(2, 1, "done", 9, 8, b"\x01", (1,), (1,),
                                                 {"hb.decode": 1}, (((0, 0), (0, 1)),),
                                                 ((1, 1),)), "query"),
        Record(1.0, keys.state(M, 3), Opaque("future_kind", {"robot": 2, "covered": b"\x01",
                                                             "dead": [1]}), "query"),
        Record(1.1, keys.sim_cover(M, 1), Gap(keys.sim_cover(M, 1), "sim/cover", 12, 0.25,
                                              1.1), "gap"),
        Record(1.2, keys.everything(M), Gap(keys.everything(M), "unknown", 1, None, 1.2),
               "gap"),
    ]


def test_every_scripted_record_round_trips(tmp_path: Path) -> None:
    records = run_mission(open_room(), two_robot_walks()).records + samples()
    path = tmp_path / "rec.jsonl"
    write(path, records)
    back = read_recording(path)
    assert back.errors == ()
    assert back.header == HEADER
    assert len(back.records) == len(records)
    for got, sent in zip(back.records, records, strict=True):
        assert (got.t, got.key, got.via, got.kind) == (sent.t, sent.key, sent.via, sent.kind)
        if isinstance(sent.msg, Opaque):
            assert got.msg.fields["covered"] == b"\x01" and list(got.msg.fields["dead"]) == [1]
        else:
            assert got.msg == sent.msg


@pytest.mark.parametrize("fields", [
    {"key": "k", "family": "f", "missed": 0, "since": None, "until": 1.0},
    {"key": "k", "family": "f", "missed": 2, "since": "x", "until": 1.0},
    {"key": "k", "family": "f", "missed": 2, "since": None},
    {"key": "k", "family": "f", "missed": 2, "since": None, "until": 1.0, "more": 1},
])
def test_malformed_gap_records_are_refused(fields: dict[str, object]) -> None:
    line = json.dumps({"t": 1.0, "key": "k", "via": "gap", "kind": "gap", "msg": fields})
    with pytest.raises(DecodeError, match="gap needs"):
        parse_line(line)


def test_lines_are_strict_json(tmp_path: Path) -> None:
    for record in samples():
        line = record_line(record)
        json.loads(line, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))


def test_malformed_lines_are_reported_by_number_and_skipped(tmp_path: Path) -> None:
    records = run_mission(open_room(), two_robot_walks()).records[:5]
    path = tmp_path / "rec.jsonl"
    write(path, records)
    lines = path.read_text().splitlines()
    good = json.loads(lines[2])
    bad_field = dict(good, msg=dict(good["msg"], robot="zero"))
    lines[1:1] = ["{not json"]                      # line 2
    lines[3:3] = [json.dumps(bad_field)]            # line 4
    lines.append(json.dumps({"t": 1.0, "key": "k", "kind": "cover"}))  # no msg
    path.write_text("\n".join(lines) + "\n")
    back = read_recording(path)
    assert [e.line for e in back.errors] == [2, 4, len(lines)]
    assert "robot" in back.errors[1].reason
    assert len(back.records) == len(records)


@pytest.mark.parametrize("first, needle", [
    ("", "not an mstc recording"),
    ('{"schema": "mstc-record", "version": 99, "wire_version": 1}', "version 99"),
    ('{"schema": "mstc-record", "version": 1, "wire_version": 42}', "wire schema version 42"),
])
def test_unusable_files_are_one_readable_error(tmp_path: Path, first: str, needle: str) -> None:
    path = tmp_path / "x.jsonl"
    path.write_text(first + "\n")
    with pytest.raises(RecordingError, match=needle):
        read_recording(path)
    with pytest.raises(RecordingError, match="cannot read"):
        read_recording(tmp_path / "missing.jsonl")


def test_unknown_kinds_are_kept_opaque_and_garbage_raises() -> None:
    raw = msgpack.packb({"_kind": "future_kind", "_v": SCHEMA_VERSION, "x": 1})
    assert decode_payload(raw) == Opaque("future_kind", {"x": 1})
    known_but_wrong = msgpack.packb({"_kind": "cover", "_v": SCHEMA_VERSION, "x": 1})
    for payload in (b"\xc1", known_but_wrong,
                    msgpack.packb({"_kind": "future_kind", "_v": 99}), msgpack.packb([1])):
        with pytest.raises(DecodeError):
            decode_payload(payload)
    msg = samples()[3].msg
    assert decode_payload(encode(msg)) == msg


def test_parse_line_rejects_bad_envelopes() -> None:
    for text in ('[]', '{"t": "x", "key": "k", "kind": "cover", "msg": {}}',
                 '{"t": 1, "key": "k", "kind": "cover", "via": "pigeon", "msg": {}}',
                 '{"t": 1, "key": "k", "kind": "token", "msg": {"robot": 1}}'):
        with pytest.raises((ValueError, DecodeError)):
            parse_line(text)


def test_older_recordings_keep_every_kind_that_has_not_changed_since(tmp_path: Path) -> None:
    """A recording of generation 1: lines of kinds unchanged since are read; an AgentState line
    (its fields changed in generation 2) is a line error naming the change, not a lost file."""
    records = run_mission(open_room(), two_robot_walks()).records + samples()
    path = tmp_path / "old.jsonl"
    with RecordWriter(path, Header(M, 1_700_000_000.0, "test", 1)) as writer:
        for record in records:
            writer.write(record)
    back = read_recording(path)
    assert back.header.wire_version == 1
    # agent_state and world changed in generation 2, status (its roster) in 4, heartbeat
    # (said / heard) in 5: the schema table's `since` says which lines an old file loses
    changed = [r for r in records if KIND_SINCE.get(getattr(r.msg, "KIND", ""), 1) > 1]
    kinds = {r.msg.KIND for r in changed}
    assert {"agent_state", "world", "status"} <= kinds, kinds
    assert len(back.errors) == len(changed)
    assert all(any(e.reason.startswith(f"{kind} of schema version 1: its fields changed in "
                                       f"version {KIND_SINCE[kind]} ") for kind in kinds)
               for e in back.errors)
    assert len(back.records) == len(records) - len(changed)


def test_payload_generations_newer_than_ours_or_older_than_the_kind_are_refused() -> None:
    agent = next(r.msg for r in samples() if isinstance(r.msg, AgentState))
    raw = msgpack.unpackb(encode(agent), raw=False)
    for version, needle in ((1, "changed in version 2"), (SCHEMA_VERSION + 1, "expected 1..")):
        with pytest.raises(DecodeError, match=needle):
            decode_payload(msgpack.packb(dict(raw, _v=version), use_bin_type=True))
    assert decode_payload(msgpack.packb(dict(raw, _v=2), use_bin_type=True)) == agent
