"""The plain aliases every message module shares.

Conventions: robots are ints; a pose is (row, col, heading) in sub-cells with heading
numbered as planner.geometry.Heading (0=N 1=E 2=S 3=W); ``sim_time`` is simulated seconds;
``incarnation`` grows each time a robot's process (re)starts so that stale lives can be
fenced.
"""

from planner.geometry import Cell as Cell
from planner.geometry import SubCell as SubCell

Pose = tuple[int, int, int]  # planner.geometry.Pose.as_tuple(), as it travels
SummaryValue = int | float | str
