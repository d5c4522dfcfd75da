"""``mstc report`` on a recording of ``mstc tree-fleet``: the recording replayed into the fleet
model, whose tree mission feeds the robots' own reports to the launcher's TeamObserver, and
the same verdict the launcher gives (deploy.tree_verdict) against the lockstep run with the
same deaths. The tree, algorithm and team size come from the mission status the launcher
repeats while the mission runs."""

from __future__ import annotations

from bus.messages import TreeReport
from deploy.errors import RecordingError
from deploy.monitor.model import FleetModel
from deploy.monitor.types import Recording
from deploy.tree_verdict import lockstep_run, summarize
from planner.treecover.trees import tree_from_spec


def tree_model(recording: Recording) -> FleetModel | None:
    """The replayed model if this is a recording of a tree mission, else None."""
    if not any(isinstance(r.msg, TreeReport) for r in recording.records):
        return None
    model = FleetModel(max_events=10_000)
    for record in recording.records:
        model.apply(record)
    if model.tree.setup is None:
        raise RecordingError("a tree-coverage recording without the launcher's mission status "
                             "(which tree, algorithm, team): it cannot be judged")
    if model.tree.observer is None:
        raise RecordingError(f"the recording's tree cannot be built: {model.tree.unusable}")
    if model.tree.joined_at is not None:
        raise RecordingError(f"the recording starts at step {model.tree.joined_at} of the tree "
                             f"mission, not at its beginning: it cannot be judged")
    return model


def build_tree_report(model: FleetModel) -> dict[str, object]:
    """The tree-fleet summary (figures and verdict) recomputed from the recording alone."""
    setup, observer = model.tree.setup, model.tree.observer
    assert setup is not None and observer is not None
    # a robot lost at the last step has no next step to confirm it: close with the deaths
    observer.finish({robot for robot, _ in model.deaths})
    seen = observer.run()
    tree = tree_from_spec(setup.tree)
    lockstep, cuts = lockstep_run(tree, setup.robots, setup.algo, seen.deaths)
    return summarize(tree, lockstep, seen, lockstep_cuts=cuts)
