"""Counting of dropped messages: malformed payloads, overflowing buffers, failed replies."""

from __future__ import annotations

import logging
import threading
from collections import Counter

_log = logging.getLogger("mstc.bus.drops")


class DropCounter:
    """Counts drops per (key kind, reason); logs the first drop of each key kind only, so a
    flood of garbage on one key cannot flood the log. Thread-safe (Zenoh threads count
    buffer overflows, the event loop counts decode failures)."""

    def __init__(self, logger: logging.Logger | None = None) -> None:
        self._counts: Counter[tuple[str, str]] = Counter()
        self._logged: set[str] = set()
        self._lock = threading.Lock()
        self._log = logger or _log

    def count(self, key_kind: str, reason: str, detail: str = "", n: int = 1) -> None:
        with self._lock:
            self._counts[(key_kind, reason)] += n
            first = key_kind not in self._logged
            self._logged.add(key_kind)
        if first:
            self._log.warning("dropping message on %s key (%s): %s (further drops of this "
                              "kind are only counted)", key_kind, reason, detail)

    def total(self, key_kind: str | None = None, reason: str | None = None) -> int:
        with self._lock:
            return sum(n for (kind, why), n in self._counts.items()
                       if (key_kind is None or kind == key_kind)
                       and (reason is None or why == reason))

    def snapshot(self) -> dict[tuple[str, str], int]:
        with self._lock:
            return dict(self._counts)
