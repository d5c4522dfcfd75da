"""Errors of the simulated hardware: a command the world refuses, or a body that cannot act.

Command errors become an ``HwReply`` status ("rejected", "failed"); none of them may stop the
server, so they are all caught by class where the reply is built.
"""

from __future__ import annotations


class SimHwError(Exception):
    """Base class of the simulated hardware's errors."""


class CommandRejected(SimHwError):
    """The command is malformed or not allowed now (unknown robot, sensor, or sonar mode)."""


class BodyFailedError(SimHwError):
    """The body's motors are dead: it cannot move, turn or sense."""


class BodyFrozenError(SimHwError):
    """The body is frozen (a hung robot): the caller must wait until it is unfrozen."""


class BodyBusyError(SimHwError):
    """The body is already in a motion: one command at a time per body."""
