"""Exceptions of the bus package. User mistakes (bad endpoint, bad config file, port taken)
are ConfigError/RouterError and should be printed as one line by the command that hit them."""

from __future__ import annotations


class BusError(Exception):
    """Base class of every error raised by bus/."""


class KeyExprError(BusError, ValueError):
    """A mission name or robot id that cannot be part of a key expression."""


class DecodeError(BusError):
    """A payload that is not a valid message of the expected type(s)."""


class EncodeError(BusError):
    """A message whose fields do not match its declared types (a programming error)."""


class ConfigError(BusError):
    """Bad connection settings: endpoint, mode, lease or Zenoh config file."""


class RouterError(BusError):
    """The router could not start (e.g. its listen port is taken)."""


class BusClosedError(BusError):
    """The bus or subscription was closed while someone was waiting on it."""


class QueryError(BusError):
    """A query failed as a whole (no route, invalid selector)."""
