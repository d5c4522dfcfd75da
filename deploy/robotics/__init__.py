"""Robotics viewers and formats: Foxglove (live WebSocket, MCAP), rosbag2 and ROS 2 types.

Needs the optional ``robotics`` extra (``pip install 'mstc-swarm[robotics]'``); commands
call :func:`require_extra` first so that a missing package is one line, not a traceback.
"""

from __future__ import annotations

import importlib.util

from deploy.errors import UsageError

EXTRA_MODULES = {"foxglove": "foxglove-sdk", "foxglove_schemas_protobuf":
                 "foxglove-schemas-protobuf", "mcap": "mcap", "rosbags": "rosbags"}


def require_extra() -> None:
    """UsageError naming the missing packages of the ``robotics`` extra, if any."""
    missing = [dist for module, dist in EXTRA_MODULES.items()
               if importlib.util.find_spec(module) is None]
    if missing:
        raise UsageError(f"needs {', '.join(missing)}: pip install 'mstc-swarm[robotics]'")
