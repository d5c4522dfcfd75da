"""Motion durations (rest-to-rest trapezoid) and the simulated clocks."""

from __future__ import annotations

import asyncio
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simhw.clock import FastClock, ScaledClock, make_clock
from simhw.kinematics import Kinematics, profile_time

positive = st.floats(0.01, 10.0, allow_nan=False)


def farthest(t: float, v: float, a: float) -> float:
    """Farthest rest-to-rest distance in time t: accelerate half-way (capped at v), brake."""
    if t <= 2 * v / a:
        return a * t * t / 4
    return v * (t - v / a)


def shortest_time(distance: float, v: float, a: float) -> float:
    """Invert ``farthest`` by bisection: the least time that reaches ``distance``."""
    lo, hi = 0.0, 1.0
    while farthest(hi, v, a) < distance:
        hi *= 2
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if farthest(mid, v, a) < distance else (lo, mid)
    return hi


@pytest.mark.parametrize(("d", "v", "a"), [(0.4, 0.3, 0.5), (0.05, 0.3, 0.5), (1.0, 1.0, 0.5),
                                           (math.pi / 2, 1.0, 2.0)])
def test_profile_is_the_time_optimal_rest_to_rest_move(d: float, v: float, a: float) -> None:
    assert profile_time(d, v, a) == pytest.approx(shortest_time(d, v, a), rel=1e-9)


@settings(max_examples=100, deadline=None)
@given(positive, positive, positive)
def test_profile_bounds(d: float, v: float, a: float) -> None:
    t = profile_time(d, v, a)
    # Never faster than cruising at top speed throughout, nor than pure acceleration.
    assert t >= d / v - 1e-12
    assert t >= 2 * math.sqrt(d / a) - 1e-9
    # Continuous where the profile changes shape (d = v^2 / a).
    knee = v * v / a
    assert profile_time(knee, v, a) == pytest.approx(2 * math.sqrt(knee / a))


@settings(max_examples=60, deadline=None)
@given(positive, positive, positive)
def test_profile_grows_with_distance(d: float, v: float, a: float) -> None:
    assert profile_time(d * 1.5, v, a) > profile_time(d, v, a)


def test_kinematics_primitives() -> None:
    k = Kinematics(speed=0.3, acceleration=0.5, turn_rate=1.0, angular_acceleration=2.0,
                   sub_cell_m=0.4)
    assert k.forward_s() == pytest.approx(0.4 / 0.3 + 0.3 / 0.5)
    assert k.turn_s() == pytest.approx(math.pi / 2 + 0.5)
    assert k.turn_s(2) > k.turn_s() and k.turn_s(-1) == k.turn_s(1)
    assert k.forward_s(0) == 0.0


@pytest.mark.parametrize("field", ["speed", "acceleration", "turn_rate", "sub_cell_m"])
@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, math.inf])
def test_kinematics_rejects_bad_numbers(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        Kinematics(**{field: value})


async def test_fast_clock_keeps_one_timeline_per_lane() -> None:
    clock = FastClock()
    assert await clock.run(0, 2.0) == (0.0, 2.0)
    assert await clock.run(1, 1.0) == (0.0, 1.0)  # concurrent bodies do not add up
    assert await clock.run(0, 0.5) == (2.0, 2.5)
    assert clock.now() == 2.5 and clock.lane_now(1) == 1.0


async def test_scaled_clock_uses_an_injected_wall_clock() -> None:
    wall = [100.0]
    clock = ScaledClock(10.0, wall=lambda: wall[0])
    wall[0] = 100.5
    assert clock.now() == pytest.approx(5.0)
    start, end = await clock.run(0, 0.0)
    assert end - start == 0.0


async def test_scaled_clock_waits_duration_over_scale() -> None:
    clock = ScaledClock(1000.0)
    loop = asyncio.get_running_loop()
    before = loop.time()
    start, end = await clock.run(0, 20.0)  # 20 ms of wall time
    assert end - start == 20.0
    assert loop.time() - before >= 0.019


@pytest.mark.parametrize(("scale", "kind"), [(0, FastClock), (math.inf, FastClock),
                                            (2.0, ScaledClock)])
def test_make_clock(scale: float, kind: type) -> None:
    assert isinstance(make_clock(scale), kind)


@pytest.mark.parametrize("scale", [-1.0, math.nan, -math.inf])
def test_make_clock_rejects_bad_scales(scale: float) -> None:
    with pytest.raises(ValueError, match="time_scale"):
        make_clock(scale)
