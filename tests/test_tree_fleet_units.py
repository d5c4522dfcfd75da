"""Tree coverage in the fleet, the pure parts: wire messages and keys, the radio's range rule,
the team replica every agent runs, the step barrier of trail repair, and the launcher's
observer."""

from __future__ import annotations

from typing import Any

import msgpack
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_bus_codec import st_message

from agent.tree.barrier import StepVerdict, judge_step, reachable_nodes
from bus import codec, keys
from bus.codec import decode, decode_any, encode
from bus.errors import DecodeError
from bus.messages import RadioStats, TreeReport
from deploy.tree_observer import TeamObserver, connected
from planner.treecover.failures import run_with_failures
from planner.treecover.sim import run_coverage
from planner.treecover.team import TeamReplica, assign
from planner.treecover.trees import general_tree, perfect_tree
from planner.treecover.types import Move, Tree
from simhw.radio_model import RadioModel, in_range

# --- wire ----------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(st.sampled_from([TreeReport, RadioStats]).flatmap(st_message))
def test_tree_messages_round_trip(msg: Any) -> None:
    payload = encode(msg)
    assert decode(payload, type(msg)) == msg
    assert decode_any(payload) == msg


@pytest.mark.parametrize(("mutate", "match"), [
    (lambda r: r.pop("sender"), "missing"),
    (lambda r: r.update({"hops": 1}), "extra"),
    (lambda r: r.update({"node": "3"}), "node"),
    (lambda r: r.update({"step": True}), "step"),
    (lambda r: r.update({codec.KIND_FIELD: "radio_stats"}), "kind"),
])
def test_tree_report_decoding_is_strict(mutate: Any, match: str) -> None:
    raw = msgpack.unpackb(encode(TreeReport(1, 1, 4, 7, 2)))
    mutate(raw)
    with pytest.raises(DecodeError, match=match):
        decode(msgpack.packb(raw, use_bin_type=True), TreeReport)


def test_tree_keys_parse_back_and_wildcards_match_only_their_family() -> None:
    import zenoh

    out, inbox = keys.tree_outbox("m", 3), keys.tree_inbox("m", 3)
    assert keys.parse(out) == keys.ParsedKey("m", "tree/outbox", 3)
    assert keys.parse(inbox) == keys.ParsedKey("m", "tree/inbox", 3)
    assert keys.parse(keys.tree_radio("m")) == keys.ParsedKey("m", "tree/radio")
    assert keys.parse("mstc/m/tree/robot/x/outbox") is None
    assert keys.parse("mstc/m/tree/robot/3/other") is None

    def matches(pattern: str, key: str) -> bool:
        return bool(zenoh.KeyExpr(pattern).intersects(zenoh.KeyExpr(key)))

    assert matches(keys.all_tree_outboxes("m"), out)
    assert not matches(keys.all_tree_outboxes("m"), inbox)
    assert matches(keys.all_tree_inboxes("m"), inbox)
    assert not matches(keys.all_tree_inboxes("m"), out)


# --- radio ---------------------------------------------------------------------------------

# root 0 - children 1, 2; 1 - children 3, 4; 2 - children 5, 6
PARENT = perfect_tree(2, 2).parent.tolist()


def test_range_is_same_or_adjacent_node() -> None:
    assert in_range(PARENT, 1, 1)
    assert in_range(PARENT, 0, 1) and in_range(PARENT, 1, 0)
    assert in_range(PARENT, 1, 4)
    assert not in_range(PARENT, 0, 4)  # two edges apart
    assert not in_range(PARENT, 1, 2)  # siblings
    assert not in_range(PARENT, 3, 4)


def test_radio_delivers_only_in_range_and_counts_refusals() -> None:
    radio: RadioModel[str] = RadioModel(PARENT, 3)
    assert radio.locate(0, 0, 0) == []
    assert radio.locate(1, 0, 1) == []
    assert radio.locate(2, 0, 4) == []
    assert radio.transmit(2, 0, "from 2") == [(1, "from 2")]
    assert radio.counters.refused == 1  # robot 0, two edges away
    assert sorted(radio.transmit(1, 0, "from 1")) == [(0, "from 1"), (2, "from 1")]
    assert radio.counters.deliveries == 3


def test_radio_judges_a_late_robot_where_it_stands_at_that_step() -> None:
    radio: RadioModel[str] = RadioModel(PARENT, 3)
    for robot, node in ((0, 0), (1, 0), (2, 0)):
        radio.locate(robot, 0, node)
    radio.locate(0, 1, 1)
    radio.locate(1, 1, 4)
    # robot 2 still stands at step 0 on the root; at step 1 it will be on node 2
    assert radio.transmit(1, 1, "x") == [(0, "x")]
    assert radio.pending == 1
    assert radio.locate(2, 1, 2) == []  # node 2 is not in range of node 4
    assert radio.counters.refused == 1 and radio.pending == 0
    radio.locate(0, 2, 0)
    radio.locate(1, 2, 1)
    assert radio.transmit(0, 2, "y") == [(1, "y")]
    assert radio.locate(2, 2, 2) == [(2, "y")]  # held, then delivered: 2 is next to 0


def test_radio_drops_unlocated_senders_and_forgets_finished_steps() -> None:
    radio: RadioModel[str] = RadioModel(PARENT, 2)
    assert radio.transmit(0, 0, "who?") == []
    assert radio.counters.unlocated == 1
    for step in range(3):
        radio.locate(0, step, 0)
        radio.locate(1, step, 1)
    assert radio.node_of(0, 0) is None  # both robots are past step 0
    assert radio.node_of(0, 2) == 0
    with pytest.raises(ValueError, match="node"):
        radio.locate(0, 3, 7)


# --- team replica --------------------------------------------------------------------------


def test_assign_gives_moves_to_robots_in_id_order() -> None:
    positions = [0, 0, 1, 0]
    after = assign([Move(0, 2, 2), Move(1, 0, 1), Move(0, 1, 1)], positions)
    assert after == [2, 2, 0, 1]
    with pytest.raises(ValueError, match="needs"):
        assign([Move(1, 3, 2)], positions)


CASES = [(perfect_tree(2, 3), 4), (perfect_tree(3, 3), 7), (perfect_tree(2, 4), 1),
         (general_tree(2, 5, 3, 2, 1), 6), (perfect_tree(3, 4), 8)]


@pytest.mark.parametrize("algo", ["cocta", "ncocta"])
@pytest.mark.parametrize(("tree", "robots"), CASES)
def test_replica_walks_exactly_the_lockstep_run(tree: Tree, robots: int, algo: str) -> None:
    lockstep = run_coverage(tree, robots, algo)
    replica = TeamReplica(tree, robots, algo)
    observer = TeamObserver(tree, robots)
    visits: list[int] = []
    while True:
        for robot, node in enumerate(replica.positions):
            observer.on_transmission(TreeReport(robot, 1, replica.step, node, robot))
        counts: dict[int, int] = {}
        for node in replica.positions:
            counts[node] = counts.get(node, 0) + 1
        assert counts == replica.state.at  # robots agree with the counts decide used
        visits.append(len(counts))
        if replica.done():
            break
        replica.advance()
    assert replica.step == lockstep.time
    assert tuple(visits[1:]) == lockstep.occupied
    seen = observer.run()
    assert seen.coverage_time == lockstep.time
    assert seen.visited == tree.n and seen.connected and seen.jumps == 0


# --- observer ------------------------------------------------------------------------------


def test_observer_flags_disconnection_and_jumps_and_ignores_relays() -> None:
    tree = perfect_tree(2, 2)
    observer = TeamObserver(tree, 2)
    steps = [(0, 0), (1, 2), (4, 2)]  # robot 0 walks 0 -> 1 -> 4, robot 1 0 -> 2
    for step, (a, b) in enumerate(steps):
        observer.on_transmission(TreeReport(0, 1, step, a, 0))
        observer.on_transmission(TreeReport(1, 1, step, b, 1))
        observer.on_transmission(TreeReport(1, 1, step, 6, 0))  # a relay: not a position
    seen = observer.run()
    assert seen.steps == 3 and seen.transmissions == 9
    assert not seen.connected  # step 1: nodes 1 and 2 without the root
    assert seen.jumps == 0 and seen.coverage_time is None
    observer.on_transmission(TreeReport(0, 1, 3, 3, 0))  # 4 -> 3: siblings, not an edge
    observer.on_transmission(TreeReport(1, 1, 3, 2, 1))
    assert observer.run().jumps == 1
    assert connected(tree.parent.tolist(), {0, 1, 4})
    assert not connected(tree.parent.tolist(), {0, 4})


def test_tree_report_sets_must_be_int_arrays() -> None:
    raw = msgpack.unpackb(encode(TreeReport(1, 1, 4, 7, 2, ((3, 2),), (3, 5))))
    assert raw["gone"] == [[3, 2]] and raw["dead"] == [3, 5]
    raw["gone"] = [3]
    with pytest.raises(DecodeError, match="gone"):
        decode(msgpack.packb(raw, use_bin_type=True), TreeReport)


# --- trail repair in the fleet: the step barrier, the replica, the observer ----------------


def test_a_step_waits_for_every_live_robot_in_hearing() -> None:
    positions, alive = [0, 1, 3, 2], [True] * 4  # robot 2 on node 3, below robot 1
    ready = judge_step(PARENT, positions, alive, 0, {0, 1, 2, 3}, {}, 0.0, 1.0)
    assert ready == StepVerdict(True, (), (), None)
    waiting = judge_step(PARENT, positions, alive, 0, {0, 1, 3}, {}, 0.0, 1.0)
    assert not waiting.ready and waiting.waiting_for == (2,) and waiting.wake_in is None


def test_a_dead_robot_without_a_report_is_absent_once_its_death_settles() -> None:
    positions, alive = [0, 1, 3, 2], [True] * 4
    early = judge_step(PARENT, positions, alive, 0, {0, 1, 3}, {2: 10.0}, 10.25, 1.0)
    assert not early.ready and early.waiting_for == (2,) and early.wake_in == 0.75
    late = judge_step(PARENT, positions, alive, 0, {0, 1, 3}, {2: 10.0}, 11.0, 1.0)
    assert late.ready and late.absent == (2,)
    removed = judge_step(PARENT, positions, [True, True, False, True], 0, {0, 1, 3}, {2: 1.0},
                         1.5, 1.0)  # removed at an earlier step: no longer expected
    assert removed.ready and removed.absent == ()


def test_robots_cut_off_by_a_dead_robot_that_reported_are_not_waited_for() -> None:
    # robot 1 reported this step and then died: it relays nothing, so robot 2 below it cannot
    # be heard; robot 1 stays in the team until the step its report is missing
    positions, alive = [0, 1, 3, 2], [True] * 4
    verdict = judge_step(PARENT, positions, alive, 0, {0, 1, 3}, {1: 0.0}, 0.1, 1.0)
    assert verdict.ready and verdict.absent == () and verdict.waiting_for == ()
    assert reachable_nodes(PARENT, [0, 1, 3, 2], 3) == {0, 1, 2, 3}
    assert reachable_nodes(PARENT, [0, 3, 2], 3) == {3}
    assert reachable_nodes(PARENT, [0, 2], 4) == set()


@pytest.mark.parametrize("algo", ["cocta", "ncocta"])
def test_replica_with_a_loss_walks_the_lockstep_run_and_the_observer_sees_it(algo: str) -> None:
    tree, robots, victim, lost_at = perfect_tree(3, 3), 7, 4, 9
    lockstep = run_with_failures(tree, robots, algo, {victim: lost_at})
    replica = TeamReplica(tree, robots, algo)
    observer = TeamObserver(tree, robots)
    while True:
        gone = tuple(sorted(replica.removed.items()))
        for robot, node in enumerate(replica.positions):
            if replica.alive[robot] and not (robot == victim and replica.step == lost_at):
                observer.on_transmission(TreeReport(robot, 1, replica.step, node, robot, gone))
        if replica.step == lost_at:
            replica.remove([victim])
        if replica.done():
            break
        replica.advance()
    assert replica.step == lockstep.result.time
    observer.finish([victim])
    seen = observer.run()
    assert seen.deaths == {victim: lost_at}
    assert seen.coverage_time == lockstep.result.time and seen.visited == tree.n
    assert seen.connected and seen.jumps == 0
    assert seen.cut_at_death == lockstep.cut_at_death


def test_observer_closes_a_death_step_when_the_next_step_lists_the_robot_gone() -> None:
    tree = perfect_tree(2, 2)
    observer = TeamObserver(tree, 3)
    for robot in range(3):
        observer.on_transmission(TreeReport(robot, 1, 0, 0, robot))
    observer.on_transmission(TreeReport(0, 1, 1, 0, 0))
    observer.on_transmission(TreeReport(1, 1, 1, 2, 1))  # robot 2 never reports step 1
    assert observer.complete == 0
    observer.on_transmission(TreeReport(0, 1, 2, 0, 0, ((2, 1),)))
    assert observer.complete == 1 and observer.deaths == {2: 1}
    observer.on_transmission(TreeReport(1, 1, 2, 0, 1, ((2, 1),)))
    assert observer.complete == 2 and observer.run().connected
