"""Seeded message faults at the bridge's boundary: drop, duplicate, delay, reorder.

This machine's kernel has no netem, so message loss and latency are made here, where a
process's messages leave (``Bus.publish``) and arrive (``Subscription``): a Bus given a
:class:`MessageFaults` asks it, per message, what becomes of it. Rules are per key family
(``bus.keys.kind_of``: "progress", "status", "ormstc", "hb", ...; ``*`` for the others).
Queries, replies and liveliness tokens are not touched: they model request/response links
whose loss the hardware timeout already covers, and the tokens the transport itself.

A spec is one string (the ``MSTC_FAULTS`` environment variable of an agent, or
``mstc up --faults``)::

    seed=7;progress.drop=0.1;*.dup=0.05;ormstc.delay=0.3;*.reorder=0.1;window=0.2

``drop``/``lose``/``dup``/``reorder`` are probabilities per message (``drop`` at the
publisher, so every receiver misses it; ``lose`` at one receiver), ``delay`` the longest extra
latency in seconds (uniform from 0), ``window`` how long a reordered message is held back
(later ones overtake it). The random stream is seeded: the same spec gives
the same decisions for the same sequence of messages.
"""

from __future__ import annotations

import os
import random
import threading
from dataclasses import dataclass, field

from bus.errors import BusError

ENV = "MSTC_FAULTS"
ANY = "*"
_ACTIONS = ("drop", "lose", "dup", "delay", "reorder")


class FaultSpecError(BusError):
    """A message-fault spec that cannot be read (one line for the user)."""


@dataclass(frozen=True)
class FaultRates:
    drop: float = 0.0  # lost for every receiver (at the publisher)
    lose: float = 0.0  # lost for this receiver only (at the subscriber)
    dup: float = 0.0
    delay: float = 0.0  # seconds, the longest extra latency
    reorder: float = 0.0


@dataclass(frozen=True)
class FaultSpec:
    seed: int = 0
    rules: dict[str, FaultRates] = field(default_factory=dict)
    window: float = 0.2

    def rates(self, kind: str) -> FaultRates | None:
        """The rule of a key kind: its own ("ormstc/claim"), else its family's ("ormstc"),
        else ``*``."""
        rates = self.rules.get(kind)
        if rates is None and "/" in kind:
            rates = self.rules.get(kind.split("/", 1)[0])
        return rates if rates is not None else self.rules.get(ANY)

    def text(self) -> str:
        """The spec as parse_spec reads it back."""
        items = [f"seed={self.seed}", f"window={self.window:g}"]
        for family, rates in sorted(self.rules.items()):
            for action in _ACTIONS:
                value = getattr(rates, action)
                if value:
                    items.append(f"{family}.{action}={value:g}")
        return ";".join(items)


def parse_spec(text: str) -> FaultSpec:
    """The FaultSpec of ``text`` (see the module docstring); FaultSpecError otherwise."""
    seed, window = 0, 0.2
    rules: dict[str, dict[str, float]] = {}
    for item in filter(None, (part.strip() for part in text.split(";"))):
        name, sep, value_text = item.partition("=")
        try:
            value = float(value_text)
        except ValueError:
            value = float("nan")
        if not sep or value != value:
            raise FaultSpecError(f"message faults: {item!r} is not NAME=NUMBER")
        if name == "seed":
            seed = int(value)
            continue
        if name == "window":
            window = value
            continue
        family, _, action = name.rpartition(".")
        if not family or action not in _ACTIONS:
            raise FaultSpecError(f"message faults: {name!r} is not FAMILY.ACTION with ACTION "
                                 f"one of {', '.join(_ACTIONS)}")
        if value < 0 or (action != "delay" and value > 1):
            raise FaultSpecError(f"message faults: {item!r} is out of range")
        rules.setdefault(family, {})[action] = value
    return FaultSpec(seed, {f: FaultRates(**r) for f, r in rules.items()}, window)


class MessageFaults:
    """What becomes of each message: the decisions only, the Bus carries them out.

    Receive-side decisions come from Zenoh's threads, publish-side ones from the loop: one
    lock keeps the seeded stream whole."""

    def __init__(self, spec: FaultSpec) -> None:
        self.spec = spec
        self._rng = random.Random(spec.seed)
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {action: 0 for action in _ACTIONS}

    @classmethod
    def from_env(cls) -> MessageFaults | None:
        text = os.environ.get(ENV, "").strip()
        return cls(parse_spec(text)) if text else None

    def outgoing(self, kind: str) -> list[float]:
        """Delays (seconds) of the copies of one published message to send: [] drops it,
        [0.0] sends it as it is, two entries duplicate it."""
        rates = self.spec.rates(kind)
        if rates is None:
            return [0.0]
        with self._lock:
            rng = self._rng
            if rates.drop and rng.random() < rates.drop:
                self.counts["drop"] += 1
                return []
            delay = rng.uniform(0.0, rates.delay) if rates.delay else 0.0
            if delay:
                self.counts["delay"] += 1
            if rates.reorder and rng.random() < rates.reorder:
                self.counts["reorder"] += 1
                delay += self.spec.window
            copies = [delay]
            if rates.dup and rng.random() < rates.dup:
                self.counts["dup"] += 1
                copies.append(delay + rng.uniform(0.0, self.spec.window))
            return copies

    def incoming_dropped(self, kind: str) -> bool:
        rates = self.spec.rates(kind)
        if rates is None or not rates.lose:
            return False
        with self._lock:
            dropped = self._rng.random() < rates.lose
            if dropped:
                self.counts["lose"] += 1
            return dropped
