"""Bad allocation input gives one readable PlannerError line, never a traceback of internals."""

from __future__ import annotations

import math

import pytest

from planner.allocation import allocate
from planner.errors import (
    InfeasiblePlanError,
    PlannerError,
    RobotParameterError,
    RobotPlacementError,
    UnknownAlgorithmError,
)

CASES = [
    (("opt", 10, []), {}, RobotPlacementError, "no robots"),
    (("opt", 2, [0, 1, 2]), {}, RobotPlacementError, "3 robots cannot start"),
    (("bt", 10, [3, 5, 3]), {}, RobotPlacementError, "robots 0 and 2 both start"),
    (("nb", 10, [0, 10]), {}, RobotPlacementError, "robot 1 starts at cycle index 10"),
    (("nb", 10, [-1]), {}, RobotPlacementError, "outside 0..9"),
    (("fast", 10, [0]), {}, UnknownAlgorithmError, "choose one of nb, bt, opt"),
    (("opt", 10, [0, 5]), {"speeds": [1.0]}, RobotParameterError, "1 speeds for 2 robots"),
    (("opt", 10, [0, 5]), {"speeds": [1.0, 0.0]}, RobotParameterError, "robot 1 has speed"),
    (("opt", 10, [0, 5]), {"speeds": [math.nan, 1.0]}, RobotParameterError, "robot 0"),
    (("opt", 10, [0, 5]), {"speeds": [math.inf, 1.0]}, RobotParameterError, "finite"),
    (("opt", 10, [0, 5]), {"fuel": [3]}, RobotParameterError, "1 fuel limits for 2"),
    (("opt", 10, [0, 5]), {"fuel": [3, -1]}, RobotParameterError, "robot 1 has fuel -1"),
    (("nb", 10, [0, 5]), {"fuel": [3, None]}, InfeasiblePlanError,
     "nb makes robot 0 walk 4 moves but its fuel is 3"),
]


@pytest.mark.parametrize(("args", "kwargs", "error", "message"), CASES)
def test_bad_input_is_one_readable_line(args: tuple, kwargs: dict, error: type,
                                        message: str) -> None:
    with pytest.raises(error, match=message) as caught:
        allocate(*args, **kwargs)
    assert isinstance(caught.value, PlannerError)
    assert "\n" not in str(caught.value)


def test_bt_with_enough_fuel_is_accepted() -> None:
    allocations = allocate("bt", 10, [0, 5], fuel=[4, 4])
    assert all(a.steps <= 4 for a in allocations)


def test_positions_need_not_be_sorted_and_results_are_in_robot_order() -> None:
    allocations = allocate("opt", 50, [40, 3, 17])
    assert [a.robot for a in allocations] == [0, 1, 2]
    assert [a.start_index for a in allocations] == [40, 3, 17]
