"""Strict msgpack codec for the message kinds of the wire schema (bus.messages.schema).

A payload is one msgpack map: ``{"_kind": KIND, "_v": SCHEMA_VERSION, <field>: <value>...}``
(records nested inside are plain maps of their fields; tuples are arrays). Decoding is strict
because robots act on what they hear: wrong kind, a version newer than ours or older than the
kind's last change (``bus.messages.schema.version_problem``), missing or extra fields, wrong
types and oversized payloads all raise DecodeError, and the caller counts the drop.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Callable
from typing import Any, Literal, TypeVar, Union, get_args, get_origin

import msgpack

from bus.errors import DecodeError, EncodeError
from bus.messages.schema import MESSAGE_TYPES, RECORD_TYPES, SCHEMA_VERSION, version_problem

DEFAULT_MAX_PAYLOAD = 64 * 1024
KIND_FIELD = "_kind"
VERSION_FIELD = "_v"

M = TypeVar("M")
Expected = type[M] | tuple[type[Any], ...]


Converter = Callable[[Any, str], Any]
_COMPILED: dict[tuple[Any, bool], Converter] = {}
_PLANS: dict[tuple[type[Any], bool], tuple[tuple[str, Converter], ...]] = {}
_BY_KIND: dict[Any, dict[str, type[Any]]] = {}  # expected type(s) -> kind -> type


def _error(decoding: bool) -> type[Exception]:
    return DecodeError if decoding else EncodeError


def _type_name(value: Any) -> str:
    return type(value).__name__


def _compile(tp: Any, decoding: bool) -> Converter:
    """A checker for values of field type ``tp`` that returns the wire form (encode) or the
    Python form (decode); built once per type because decoding is on every hot path."""
    key = (tp, decoding)
    conv = _COMPILED.get(key)
    if conv is None:
        conv = _COMPILED[key] = _build(tp, decoding)
    return conv


def _build(tp: Any, decoding: bool) -> Converter:
    error = _error(decoding)
    origin = get_origin(tp)
    if origin is Literal:
        return _literal(get_args(tp), error)
    if origin is Union or origin is types.UnionType:
        return _union(tuple(_compile(a, decoding) for a in get_args(tp)), tp, error)
    if origin is tuple:
        return _tuple(get_args(tp), decoding, error)
    if origin is dict:
        key_tp, value_tp = get_args(tp)
        return _dict(key_tp, value_tp, decoding, error)
    if isinstance(tp, type) and tp in RECORD_TYPES:
        return _record(tp, decoding, error)
    return _scalar(tp, error)


def _scalar(tp: Any, error: type[Exception]) -> Converter:
    if tp is type(None):
        def none(value: Any, path: str) -> Any:
            if value is not None:
                raise error(f"{path}: expected None, got {_type_name(value)}")
            return None
        return none
    if tp is float:
        def real(value: Any, path: str) -> Any:
            kind = type(value)
            if kind is float:
                return value
            if kind is int:
                return float(value)
            raise error(f"{path}: expected float, got {_type_name(value)}")
        return real
    if tp in (int, str, bytes, bool):
        # Exact type comparison: bool is a subclass of int, and True must not pass for 1.
        def exact(value: Any, path: str) -> Any:
            if type(value) is not tp:
                raise error(f"{path}: expected {tp.__name__}, got {_type_name(value)}")
            return value
        return exact
    raise TypeError(f"unsupported message field type {tp!r}")


def _literal(allowed: tuple[Any, ...], error: type[Exception]) -> Converter:
    pairs = {(type(a), a) for a in allowed}

    def literal(value: Any, path: str) -> Any:
        try:
            ok = (type(value), value) in pairs
        except TypeError:  # unhashable (array or map): certainly not a literal
            ok = False
        if not ok:
            raise error(f"{path}: {value!r} is not one of {allowed}")
        return value
    return literal


def _union(members: tuple[Converter, ...], tp: Any, error: type[Exception]) -> Converter:
    def union(value: Any, path: str) -> Any:
        for member in members:
            try:
                return member(value, path)
            except error:
                continue
        raise error(f"{path}: {value!r} matches none of {tp}")
    return union


# Field types whose values are checked by their exact type alone (bool is no int here)
_EXACT = (int, str, bytes, bool)


def _row_types(tp: Any) -> tuple[type[Any], ...] | None:
    """The exact item types of ``tp`` if it is a fixed tuple of _EXACT scalars, else None."""
    if get_origin(tp) is not tuple:
        return None
    args = get_args(tp)
    if not args or Ellipsis in args or not all(a in _EXACT for a in args):
        return None
    return tuple(args)


def _tuple(args: tuple[Any, ...], decoding: bool, error: type[Exception]) -> Converter:
    build = tuple if decoding else list
    if len(args) == 2 and args[1] is Ellipsis:
        item = _compile(args[0], decoding)

        def variadic(value: Any, path: str) -> Any:
            if not isinstance(value, (tuple, list)):
                raise error(f"{path}: expected array, got {_type_name(value)}")
            return build(item(v, f"{path}[{i}]") for i, v in enumerate(value))

        # Fast paths for the long arrays of the hot messages (a status's roster of every
        # robot, a route): one pass comparing exact types, no converter call per item, and
        # the item by item path above only for a value that fails it, to say where. A crowd
        # of 60 agents spent most of its loop decoding rosters item by item.
        if args[0] in _EXACT:
            scalar = args[0]

            def scalars(value: Any, path: str) -> Any:
                if isinstance(value, (tuple, list)) and all(type(v) is scalar for v in value):
                    return build(value)
                return variadic(value, path)
            return scalars
        row = _row_types(args[0])
        if row is not None:
            arrays = (tuple, list)

            def rows(value: Any, path: str) -> Any:
                if isinstance(value, arrays) and all(
                        type(v) in arrays and tuple(map(type, v)) == row for v in value):
                    return build(build(v) for v in value)
                return variadic(value, path)
            return rows
        return variadic
    items = tuple(_compile(a, decoding) for a in args)

    def fixed(value: Any, path: str) -> Any:
        if not isinstance(value, (tuple, list)):
            raise error(f"{path}: expected array, got {_type_name(value)}")
        if len(value) != len(items):
            raise error(f"{path}: expected {len(items)} items, got {len(value)}")
        return build(conv(v, path) for conv, v in zip(items, value, strict=True))
    return fixed


def _dict(key_tp: Any, value_tp: Any, decoding: bool, error: type[Exception]) -> Converter:
    key_conv, value_conv = _compile(key_tp, decoding), _compile(value_tp, decoding)

    def mapping(value: Any, path: str) -> Any:
        if not isinstance(value, dict):
            raise error(f"{path}: expected map, got {_type_name(value)}")
        return {key_conv(k, f"{path} key"): value_conv(v, f"{path}[{k!r}]")
                for k, v in value.items()}
    return mapping


def _record(cls: type[Any], decoding: bool, error: type[Exception]) -> Converter:
    def record(value: Any, path: str) -> Any:
        if decoding:
            if not isinstance(value, dict):
                raise error(f"{path}: expected map, got {_type_name(value)}")
            return cls(**_fields(cls, value, path, decoding))
        if type(value) is not cls:
            raise error(f"{path}: expected {cls.__name__}, got {_type_name(value)}")
        return _fields(cls, _as_dict(value), path, decoding)
    return record


def _plan(cls: type[Any], decoding: bool) -> tuple[tuple[str, Converter], ...]:
    key = (cls, decoding)
    plan = _PLANS.get(key)
    if plan is None:
        hints = typing.get_type_hints(cls)
        plan = _PLANS[key] = tuple((f.name, _compile(hints[f.name], decoding))
                                   for f in dataclasses.fields(cls))
    return plan


def _as_dict(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def _fields(cls: type[Any], raw: dict[Any, Any], path: str,
            decoding: bool) -> dict[str, Any]:
    plan = _plan(cls, decoding)
    if len(raw) != len(plan) or any(name not in raw for name, _ in plan):
        names = [name for name, _ in plan]
        missing = [name for name in names if name not in raw]
        extra = [name for name in raw if name not in names]
        raise _error(decoding)(
            f"{path}: {cls.__name__} missing fields {missing}, extra fields {extra}")
    return {name: conv(raw[name], f"{path}.{name}") for name, conv in plan}


def encode(msg: Any, *, max_size: int = DEFAULT_MAX_PAYLOAD) -> bytes:
    """Serialize a registered message; EncodeError if a field breaks its type or it is too big."""
    cls = type(msg)
    kind = getattr(cls, "KIND", None)
    if kind is None or MESSAGE_TYPES.get(kind) is not cls:
        raise EncodeError(f"{cls.__name__} is not a registered message type")
    body = _fields(cls, _as_dict(msg), kind, decoding=False)
    wire = {KIND_FIELD: kind, VERSION_FIELD: SCHEMA_VERSION, **body}
    payload: bytes = msgpack.packb(wire, use_bin_type=True)
    if len(payload) > max_size:
        raise EncodeError(f"{kind}: encoded size {len(payload)} exceeds {max_size} bytes")
    return payload


def _expected_types(expected: Expected[Any]) -> tuple[type[Any], ...]:
    return expected if isinstance(expected, tuple) else (expected,)


def decode(payload: bytes, expected: Expected[M], *,
           max_size: int = DEFAULT_MAX_PAYLOAD) -> M:
    """Parse ``payload`` as one of the ``expected`` message types, strictly (see module doc)."""
    if len(payload) > max_size:
        raise DecodeError(f"payload of {len(payload)} bytes exceeds {max_size}")
    try:
        raw = msgpack.unpackb(payload, raw=False, use_list=False, strict_map_key=False)
    # TypeError: a map key that is itself a map (unhashable); ValueError covers too deep
    # nesting and declared lengths beyond the payload.
    except (ValueError, TypeError, OverflowError, msgpack.UnpackException) as error:
        raise DecodeError(f"not msgpack: {error or type(error).__name__}") from error
    if not isinstance(raw, dict):
        raise DecodeError(f"expected a msgpack map, got {type(raw).__name__}")
    kind, version = raw.get(KIND_FIELD), raw.get(VERSION_FIELD)
    problem = version_problem(kind if isinstance(kind, str) else "", version)
    if problem is not None and (type(version) is not int or version > SCHEMA_VERSION):
        raise DecodeError(problem)  # a newer or broken generation, whatever the kind
    by_kind = _BY_KIND.get(expected)
    if by_kind is None:
        by_kind = _BY_KIND[expected] = {t.KIND: t for t in _expected_types(expected)}
    cls = by_kind.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise DecodeError(f"kind {kind!r}, expected one of {sorted(by_kind)}")
    if problem is not None:
        raise DecodeError(problem)
    body = {k: v for k, v in raw.items() if k not in (KIND_FIELD, VERSION_FIELD)}
    result: M = cls(**_fields(cls, body, cls.KIND, decoding=True))
    return result


def decode_any(payload: bytes, *, max_size: int = DEFAULT_MAX_PAYLOAD) -> Any:
    """Decode any registered message kind (recorders, monitors)."""
    return decode(payload, tuple(MESSAGE_TYPES.values()), max_size=max_size)
