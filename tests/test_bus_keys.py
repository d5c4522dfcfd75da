"""Key expressions: parse inverts the builders; wildcards match exactly their family
(zenoh's own key-expression matcher is the oracle)."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import zenoh
from hypothesis import given, settings
from hypothesis import strategies as st

from bus import keys
from bus.errors import KeyExprError

missions = st.from_regex(r"[A-Za-z0-9_.\-]{1,12}", fullmatch=True)
robots = st.integers(0, 10_000)

PER_ROBOT: dict[str, tuple[Callable[[str, int], str], Callable[[str], str]]] = {
    "hb": (keys.heartbeat, keys.all_heartbeats),
    "status": (keys.status, keys.all_statuses),
    "progress": (keys.progress, keys.all_progress),
    "event": (keys.events, keys.all_events),
    "death": (keys.death, keys.all_deaths),
    "state": (keys.state, keys.all_states),
    "ormstc/tree": (keys.ormstc_tree, lambda m: keys.all_ormstc(m, "tree")),
    "ormstc/claim": (keys.ormstc_claim, lambda m: keys.all_ormstc(m, "claim")),
    "ormstc/conn": (keys.ormstc_conn, lambda m: keys.all_ormstc(m, "conn")),
    "hw/cmd": (keys.hw_cmd, keys.all_hw_cmds),
    "sim/pose": (keys.sim_pose, keys.all_sim_poses),
    "sim/cover": (keys.sim_cover, keys.all_sim_covers),
    "sim/bump": (keys.sim_bump, keys.all_sim_bumps),
}


def matches(pattern: str, key: str) -> bool:
    return bool(zenoh.KeyExpr(pattern).intersects(zenoh.KeyExpr(key)))


@settings(max_examples=100, deadline=None)
@given(missions, robots, st.integers(0, 10_000))
def test_parse_inverts_every_builder(mission: str, robot: int, incarnation: int) -> None:
    for kind, (build, pattern) in PER_ROBOT.items():
        key = build(mission, robot)
        assert keys.parse(key) == keys.ParsedKey(mission, kind, robot)
        assert keys.kind_of(key) == kind
        # The family wildcard matches this key and no other family's key.
        for other_kind, (other_build, _) in PER_ROBOT.items():
            assert matches(pattern(mission), other_build(mission, robot)) == (
                other_kind == kind)
        assert matches(keys.everything(mission), key)
        assert not matches(keys.everything(mission + "x"), key)
    alive = keys.alive(mission, robot, incarnation)
    assert keys.parse(alive) == keys.ParsedKey(mission, "alive", robot, incarnation)
    assert matches(keys.all_alive(mission), alive)
    for build_plain, kind in ((keys.hw_admin, "hw/admin"), (keys.world, "sim/world"),
                              (keys.mission_status, "mission"),
                              (keys.mission_state, "state/mission")):
        assert keys.parse(build_plain(mission)) == keys.ParsedKey(mission, kind)
    assert matches(keys.all_states(mission), keys.mission_state(mission))


@pytest.mark.parametrize("key", ["", "mstc", "other/m/hb/1", "mstc/m/hb/x", "mstc/m/hb/-1",
                                 "mstc/m/hb/1/2", "mstc/m/alive/1", "mstc/m/nope/1",
                                 "mstc/m*/hb/1", "mstc/m/hw/1/reply", "mstc/m/sim/tree/1",
                                 "mstc/m/ormstc/pose/1", "mstc/m/state/x"])
def test_foreign_keys_do_not_parse(key: str) -> None:
    assert keys.parse(key) is None
    assert keys.kind_of(key) == "foreign"


@pytest.mark.parametrize("mission", ["", "a/b", "*", "**", "a b", "m$x", "@admin"])
def test_unsafe_missions_are_refused(mission: str) -> None:
    with pytest.raises(KeyExprError, match="mission"):
        keys.heartbeat(mission, 1)


@pytest.mark.parametrize("robot", [-1, True, 1.0, "3"])
def test_bad_robot_ids_are_refused(robot: object) -> None:
    with pytest.raises(KeyExprError, match="robot"):
        keys.heartbeat("m", robot)  # type: ignore[arg-type]
