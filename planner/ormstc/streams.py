"""Loss detection and repair for one robot's ORMSTC messages, sans-I/O.

Each robot numbers the messages it says, 1, 2, ... per life (``seq``), and its heartbeat
carries the last number it said (``said``) and, for every peer, the last number of that
peer's life it has taken in order (``heard``). Two halves, both driven with plain values:

- :class:`PeerStreams` (the receiving side) hands a peer's messages on in ``seq`` order,
  holding back what arrives after a gap (a drop, a loss, a reordering) until the gap is
  filled, drops what it already has (duplicates, resends) and keeps, per peer, its
  **acknowledgement**: how many of our messages the peer had taken when it sent the latest
  heartbeat whose ``said`` everything taken here in order covers. So the peer knew our first
  ``acked`` messages, and we know all it said before it told us (planner/ormstc/machine.py
  decides a claim only once every live peer has so acknowledged it, docs/ormstc.md), and its
  **horizon**, the receive time of the latest covered message or heartbeat (for reports).
- :class:`Resender` (the sending side) remembers when each of its messages was sent and,
  from a peer's ``heard`` in a heartbeat, which ones that peer still lacks: those older than
  ``grace`` (not merely still in flight) are said again with their own numbers, then after
  twice as long, and so on (a slow reader is not flooded).

Neither knows what the messages are: the agent (agent/ormstc/wire.py) keeps the messages,
this module the numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Generic, TypeVar

T = TypeVar("T")

NEVER = float("-inf")


@dataclass
class _Stream(Generic[T]):
    """One life of one peer."""

    life: int
    taken: int = 0  # every seq up to this one handed on
    held: dict[int, T] = field(default_factory=dict)  # seq -> message after a gap
    # (seq, received at, the receiver's own messages the peer had taken then, if said)
    digests: list[tuple[int, float, int | None]] = field(default_factory=list)
    horizon: float = NEVER
    acked: int = 0  # of a covered digest: how many of our messages the peer had taken
    said: int = 0  # the highest seq known to exist


@dataclass
class PeerStreams(Generic[T]):
    """In-order delivery, duplicate removal, gap counting and horizons per peer."""

    streams: dict[int, _Stream[T]] = field(default_factory=dict)
    duplicates: int = 0  # messages already taken or held (dup faults, resends, restatements)
    gaps: int = 0  # sequence numbers found missing (each once)

    def _stream(self, robot: int, life: int) -> _Stream[T] | None:
        """The stream of this life; None for an older life than one already heard."""
        stream = self.streams.get(robot)
        if stream is None or life > stream.life:
            stream = self.streams[robot] = _Stream(life)
        return stream if life == stream.life else None

    def stale(self, robot: int, life: int) -> bool:
        stream = self.streams.get(robot)
        return stream is not None and life < stream.life

    def receive(self, robot: int, life: int, seq: int, message: T, now: float) -> list[T]:
        """The messages to hand on, in order, now that ``message`` (number ``seq``) came."""
        stream = self._stream(robot, life)
        if stream is None:
            return []
        if seq <= stream.taken or seq in stream.held:
            self.duplicates += 1
            return []
        self._note_said(stream, seq, seq - 1)
        stream.held[seq] = message
        stream.digests.append((seq, now, None))
        out: list[T] = []
        while stream.taken + 1 in stream.held:
            stream.taken += 1
            out.append(stream.held.pop(stream.taken))
        self._advance(stream)
        return out

    def digest(self, robot: int, life: int, said: int, now: float,
               acked: int | None = None) -> None:
        """A heartbeat received at ``now`` says the peer had said ``said`` messages and had
        taken ``acked`` of ours in order (None: it named none of our life)."""
        stream = self._stream(robot, life)
        if stream is None:
            return
        self._note_said(stream, said, said)
        stream.digests.append((said, now, acked))
        self._advance(stream)

    def _note_said(self, stream: _Stream[T], seq: int, missing_to: int) -> None:
        """``seq`` exists; numbers up to ``missing_to`` not seen before are missing."""
        if seq > stream.said:
            self.gaps += max(0, missing_to - max(stream.said, stream.taken))
            stream.said = seq

    def _advance(self, stream: _Stream[T]) -> None:
        keep = []
        for digest in stream.digests:
            seq, at, acked = digest
            if seq <= stream.taken:
                stream.horizon = max(stream.horizon, at)
                if acked is not None and acked > stream.acked:
                    stream.acked = acked
            else:
                keep.append(digest)
        stream.digests = keep

    def horizon(self, robot: int) -> float:
        stream = self.streams.get(robot)
        return stream.horizon if stream is not None else NEVER

    def acked(self, robot: int) -> int:
        """How many of our messages ``robot`` had taken in order, by an acknowledgement all
        of whose preceding messages of the peer have been taken here: the peer knew our
        first ``acked`` messages, and we know everything it said before saying so."""
        stream = self.streams.get(robot)
        return stream.acked if stream is not None else 0

    def missing(self, robot: int) -> list[int]:
        """Numbers known to exist (from later messages or a heartbeat) and not yet taken."""
        stream = self.streams.get(robot)
        if stream is None:
            return []
        return [s for s in range(stream.taken + 1, stream.said + 1) if s not in stream.held]

    def heard(self) -> tuple[tuple[int, int, int], ...]:
        """(robot, life, last seq taken in order) per peer: what a heartbeat acknowledges."""
        return tuple((robot, s.life, s.taken) for robot, s in sorted(self.streams.items()))


@dataclass
class Resender:
    """Which of this robot's messages to say again, from its peers' acknowledgements.

    A message is said again once a peer still lacks it ``grace`` after it was said, then
    after twice that, and so on up to ``cap``: a peer that is merely slow to read its queue
    (a loaded host) costs a few resends, not one per heartbeat."""

    life: int
    grace: float
    cap: float = 1.0
    due: dict[int, tuple[float, float]] = field(default_factory=dict)  # seq -> (at, interval)
    resent: int = 0

    def said(self, seq: int, now: float) -> None:
        self.due[seq] = (now + self.grace, self.grace)

    def lacking(self, life: int, taken: int, now: float) -> list[int]:
        """The numbers to say again for a peer that has taken ``taken`` of life ``life``
        in order: the ones said after it whose time has come."""
        if life != self.life:
            return []
        out = []
        for seq in range(taken + 1, len(self.due) + 1):
            at, interval = self.due[seq]
            if now >= at:
                interval = min(2 * interval, self.cap)
                self.due[seq] = (now + interval, interval)
                out.append(seq)
        self.resent += len(out)
        return out
