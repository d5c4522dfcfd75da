"""The plain aliases every message module shares.

Conventions: robots are ints; a pose is (row, col, heading) in sub-cells with heading
0=N 1=E 2=S 3=W; ``sim_time`` is simulated seconds; ``incarnation`` grows each time a
robot's process (re)starts so that stale lives can be fenced.
"""

Pose = tuple[int, int, int]
SubCell = tuple[int, int]
Cell = tuple[int, int]  # (row, col) of a 2 x 2 sub-cell cell
SummaryValue = int | float | str
