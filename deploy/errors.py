"""The user mistakes of the ``mstc`` commands: each is printed as one line by the
dispatcher (deploy.cli), never as a traceback.

They live here rather than in the entry module so that ``python -m deploy.cli`` (which runs
the entry module as ``__main__``, a second copy of it) still sees the one class the commands
raise.
"""

from __future__ import annotations


class UsageError(Exception):
    """A command-line mistake found after argument parsing (bad combination, bad value)."""


class FleetError(UsageError):
    """A fleet could not be started, found or stopped; the message is one readable line."""


class RecordingError(UsageError):
    """A recording file that cannot be used at all (missing, not a recording, too new)."""
