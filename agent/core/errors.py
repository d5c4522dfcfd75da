"""Errors of the agent process. Each ends the robot's mission with its own exit code; across
processes they travel as status values (RobotEvent / MissionStatus / RobotStatus fields)."""

from __future__ import annotations


class AgentError(Exception):
    """Base class of the agent's errors; ``exit_code`` is the process's exit status."""

    exit_code = 1


class HardwareError(AgentError):
    """The body did not do what it was told (failed, frozen, bumped for good, no reply)."""

    exit_code = 1


class MissionFailedError(AgentError):
    """The mission cannot go on: a robot never announced itself, plans differ, or a peer
    reported the mission failed. The message names the robots involved."""

    exit_code = 3


class GatherTimeoutError(MissionFailedError):
    """Some robots did not announce their start (or plan digest) in time."""


class StoodDownError(AgentError):
    """The others agreed on the participants without this robot (it was heard too late):
    it takes no part, so it never covers what they divided. Not a failure of the mission."""

    exit_code = 0


class DigestMismatchError(MissionFailedError):
    """Two robots computed different plans from what should be the same inputs."""


class FencedError(AgentError):
    """This robot's life was declared dead: it must stop and never cover cells again."""

    exit_code = 4


class LeaveRequested(Exception):
    """SIGTERM/SIGINT: leave the mission cleanly (exit code 0)."""


class ConfigError(Exception):
    """A command-line mistake found after parsing (an option the algorithm needs is missing,
    an id outside the fleet): printed as one line, exit code 2, before the bus is loaded."""
