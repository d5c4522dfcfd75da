"""Recordings: every message a monitor heard, as JSON Lines (docs/protocol.md, "Recording
schema"). The first line is a header; each further line is one received message with its
receive time, key, kind and decoded fields. Bytes and non-finite floats, which JSON cannot
hold, are written as ``{"$bytes": base64}`` and ``{"$float": "inf"}``.

Reading re-validates every line with the bus codec (the fields are packed back into a wire
payload and decoded strictly), so a recording is exactly as trustworthy as the wire; a line
that does not decode is reported with its number and skipped.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol, TextIO

import msgpack

from bus.codec import KIND_FIELD, VERSION_FIELD, decode, decode_any
from bus.errors import DecodeError
from bus.messages import MESSAGE_TYPES, SCHEMA_VERSION, version_problem
from deploy.errors import RecordingError
from deploy.monitor.types import Gap, Header, LineError, Opaque, Record, Recording, TokenChange

SCHEMA = "mstc-record"
VERSION = 1
VIAS = ("sub", "query", "token", "gap")
# Recorded lines are re-checked with the codec; a WorldState of a big map exceeds the
# wire's 64 KiB default only in its JSON form, never on the wire, but be generous.
_MAX_PAYLOAD = 16 * 1024 * 1024


# --- payloads ------------------------------------------------------------------------------

def decode_payload(payload: bytes, max_size: int = _MAX_PAYLOAD) -> Any:
    """A wire payload as a bus message; an Opaque if it is a well-formed map of the current
    wire version whose kind this process has no type for; DecodeError otherwise."""
    try:
        return decode_any(payload, max_size=max_size)
    except DecodeError:
        raw = _unpack(payload)
        kind = raw.get(KIND_FIELD) if isinstance(raw, dict) else None
        if not isinstance(raw, dict) or not isinstance(kind, str) or kind in MESSAGE_TYPES \
                or version_problem(kind, raw.get(VERSION_FIELD)) is not None:
            raise
        fields = {str(k): v for k, v in raw.items() if k not in (KIND_FIELD, VERSION_FIELD)}
        return Opaque(kind, fields)


def _unpack(payload: bytes) -> Any:
    try:
        return msgpack.unpackb(payload, raw=False, use_list=False, strict_map_key=False)
    except (ValueError, msgpack.UnpackException) as error:
        raise DecodeError(f"not msgpack: {error}") from error


# --- JSON form ---------------------------------------------------------------------------

def to_json(value: Any) -> Any:
    """The JSON form of a message field value (see the module doc)."""
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else {"$float": str(value)}
    if isinstance(value, bytes):
        return {"$bytes": base64.b64encode(value).decode("ascii")}
    if isinstance(value, Opaque):
        return to_json(dict(value.fields))
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_json(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, (tuple, list)):
        return [to_json(v) for v in value]
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    raise TypeError(f"cannot record a {type(value).__name__}")


def from_json(value: Any) -> Any:
    """Undo :func:`to_json` (lists stay lists; the codec turns them into tuples)."""
    if isinstance(value, dict):
        if len(value) == 1 and "$bytes" in value:
            return base64.b64decode(value["$bytes"], validate=True)
        if len(value) == 1 and "$float" in value:
            return float(value["$float"])
        return {k: from_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [from_json(v) for v in value]
    return value


def record_line(record: Record) -> str:
    """One JSON line for ``record``."""
    return json.dumps({"t": round(record.t, 6), "key": record.key, "via": record.via,
                       "kind": record.kind, "msg": to_json(record.msg)},
                      separators=(",", ":"), allow_nan=False)


def _message(kind: str, fields: dict[str, Any], wire_version: int) -> Any:
    if kind == TokenChange.KIND:
        robot, inc, present = (fields.get(n) for n in ("robot", "incarnation", "present"))
        if type(robot) is not int or type(inc) is not int or type(present) is not bool \
                or len(fields) != 3:
            raise DecodeError("token needs exactly robot (int), incarnation (int), "
                              "present (bool)")
        return TokenChange(robot, inc, present)
    if kind == Gap.KIND:
        return _gap(fields)
    cls = MESSAGE_TYPES.get(kind)
    if cls is None:
        return Opaque(kind, fields)
    wire = {KIND_FIELD: kind, VERSION_FIELD: wire_version, **fields}
    return decode(msgpack.packb(wire, use_bin_type=True), cls, max_size=_MAX_PAYLOAD)


def _gap(fields: dict[str, Any]) -> Gap:
    key, fam, missed, since, until = (fields.get(n) for n in (
        "key", "family", "missed", "since", "until"))
    if not isinstance(key, str) or not isinstance(fam, str) or type(missed) is not int \
            or missed < 1 or not _number(until) or not (since is None or _number(since)) \
            or len(fields) != 5:
        raise DecodeError("gap needs exactly key (str), family (str), missed (int >= 1), "
                          "since (number or null), until (number)")
    assert isinstance(until, (int, float))  # checked by _number
    return Gap(key, fam, missed, None if since is None else float(since), float(until))


def _number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float)) \
        and math.isfinite(value)


def parse_line(text: str, wire_version: int = SCHEMA_VERSION) -> Record:
    """A record from one JSON line of a recording of wire generation ``wire_version``;
    ValueError (or DecodeError, e.g. a kind whose fields changed since) saying what is wrong."""
    data = json.loads(text)
    if not isinstance(data, dict):
        raise ValueError("not a JSON object")
    t, key, kind = data.get("t"), data.get("key"), data.get("kind")
    via, msg = data.get("via", "sub"), data.get("msg")
    if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
        raise ValueError(f"'t' must be a finite number, got {t!r}")
    if not isinstance(key, str) or not isinstance(kind, str):
        raise ValueError("'key' and 'kind' must be strings")
    if via not in VIAS:
        raise ValueError(f"'via' must be one of {VIAS}, got {via!r}")
    if not isinstance(msg, dict):
        raise ValueError("'msg' must be a JSON object")
    return Record(float(t), key, _message(kind, from_json(msg), wire_version), via)


# --- files -------------------------------------------------------------------------------

def header_line(header: Header) -> str:
    return json.dumps({"schema": SCHEMA, "version": VERSION,
                       "wire_version": header.wire_version, "mission": header.mission,
                       "started": header.started, "source": header.source})


def parse_header(text: str, path: Path) -> Header:
    try:
        data = json.loads(text)
    except ValueError:
        data = None
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise RecordingError(f"{path} is not an mstc recording (its first line is not a "
                             f"'{SCHEMA}' header)")
    version, wire = data.get("version"), data.get("wire_version")
    if not isinstance(version, int) or version > VERSION:
        raise RecordingError(f"{path} has recording schema version {version!r}; this mstc "
                             f"reads version {VERSION} and older")
    if type(wire) is not int or not 1 <= wire <= SCHEMA_VERSION:
        raise RecordingError(f"{path} holds wire schema version {wire!r} messages; this "
                             f"mstc decodes versions 1 to {SCHEMA_VERSION}")
    started = data.get("started")
    return Header(mission=str(data.get("mission", "")),
                  started=float(started) if isinstance(started, (int, float)) else 0.0,
                  source=str(data.get("source", "")), wire_version=wire)


def read_recording(path: Path) -> Recording:
    """Read a whole recording; bad lines are collected (and skipped), not raised."""
    try:
        with Path(path).open(encoding="utf-8", errors="replace") as stream:
            first = stream.readline()
            header = parse_header(first, Path(path))
            records: list[Record] = []
            errors: list[LineError] = []
            for number, text in enumerate(stream, start=2):
                if not text.strip():
                    continue
                try:
                    records.append(parse_line(text, header.wire_version))
                except (ValueError, DecodeError, TypeError) as error:
                    errors.append(LineError(number, str(error)))
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror or error}") from error
    return Recording(header, tuple(records), tuple(errors))


class Recorder(Protocol):
    """Where a live feed's records are kept: this module's JSON Lines, or MCAP
    (deploy.robotics.export.McapRecorder)."""

    def write(self, record: Record) -> None: ...

    def flush(self) -> None: ...

    def close(self) -> None: ...


class Recorders:
    """Several recorders fed with the same records (``--record`` and ``--record-mcap``)."""

    def __init__(self, recorders: list[Recorder]) -> None:
        self.recorders = recorders

    def write(self, record: Record) -> None:
        for recorder in self.recorders:
            recorder.write(record)

    def flush(self) -> None:
        for recorder in self.recorders:
            recorder.flush()

    def close(self) -> None:
        for recorder in self.recorders:
            recorder.close()


class RecordWriter:
    """Appends records to a new JSON Lines file; flushed by :meth:`flush` and on close."""

    def __init__(self, path: Path, header: Header) -> None:
        self.path = Path(path)
        self.lines = 0
        try:
            self._stream: TextIO = self.path.open("w", encoding="utf-8")
        except OSError as error:
            raise RecordingError(f"cannot write {path}: {error.strerror or error}") from error
        self._stream.write(header_line(header) + "\n")

    def write(self, record: Record) -> None:
        self._stream.write(record_line(record) + "\n")
        self.lines += 1

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        if not self._stream.closed:
            self._stream.close()

    def __enter__(self) -> RecordWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
