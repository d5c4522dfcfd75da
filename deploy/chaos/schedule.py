"""Seeded fault schedules: which trial runs which world, algorithm, team and faults.

Pure: a trial is a function of the campaign's options and its index, so ``mstc chaos
--only I`` with the same options re-runs trial I alone, faults and message-fault seed
included (process timing on a loaded host is the one thing a seed cannot replay).
Times are wall seconds after the trial's ``mstc up`` was started: agents announce their
start ~1-2 s in, an example-world mission at full speed ends ~5-8 s in.
"""

from __future__ import annotations

import random
from dataclasses import asdict, dataclass, field
from typing import Any

from deploy.chaos.victims import busy_at
from planner.algorithms import Family, algorithm, names

# How a trial records a fault that came once every sub-cell was covered: it tested nothing
# (a campaign counts it among the late faults, deploy.chaos.campaign.not_injected).
TOO_LATE = "too late: the mission was complete"

# Every algorithm a grid fleet runs (the registry's; tree coverage has its own launcher).
GRID_FLEET = tuple(n for n in names(fleet=True) if algorithm(n).family is not Family.TREE)
# What a trial's schedule is made of; "mixed" combines a kill, a hang and message loss.
SCENARIOS = ("none", "early-kill", "kill", "kills", "hang", "long-hang", "loss",
             "router-restart", "router-freeze", "partition", "mixed", "starve", "starve-host",
             "late-death")
# "starve" throttles one robot to a share of the CPU; "starve-host" (robot None) runs one
# busy process per core beside the whole fleet, so it starves anything else on the host too.
PROCESS_FAULTS = ("kill", "hang", "router-kill", "router-freeze", "partition", "starve")
# Deaths `mstc up` itself orders at a share of the coverage (--kill, --kill-hw), so that they
# fall in every phase of a mission whatever its world's size: "late-death" draws one. The
# other faults' times are seconds, and on a large world they all fall in its first part.
COVERAGE_FAULTS = ("kill", "body-fail")
# LookSteps only tell a report which re-entries were made to sense (no agent reads them):
# losing one blinds the recording, which is not what a loss trial tests.
LOSS_SPEC = ("*.drop=0.03;*.lose=0.03;*.dup=0.05;*.delay=0.05;*.reorder=0.05;window=0.1;"
             "look.dup=0")


@dataclass(frozen=True)
class Fault:
    """One process fault: ``kind`` in PROCESS_FAULTS, ``robot`` its target (None: the
    router; for "starve", the whole host), ``seconds`` how long a hang, freeze, partition,
    router outage or starvation lasts, ``share`` the part of each 100 ms a starved robot may
    run. With a ``mark``, ``at`` counts from the moment the target's log first shows that
    text (a phase of its life: "gathering", "participants", "driving", "completed"). With a
    ``percent``, ``at`` is unused: ``mstc up`` kills the robot's process ("kill") or fails
    its body in simhw ("body-fail") once that much of the area is covered."""

    kind: str
    at: float
    robot: int | None = None
    seconds: float = 0.0
    mark: str = ""
    share: float = 1.0
    percent: float | None = None

    @property
    def by_coverage(self) -> bool:
        """Ordered from ``mstc up``'s command line rather than injected on a clock."""
        return self.percent is not None

    def describe(self) -> str:
        if self.percent is not None:
            return f"{self.kind} robot {self.robot} at {self.percent:g} % coverage"
        host = "host" if self.kind == "starve" else "router"
        target = host if self.robot is None else f"robot {self.robot}"
        span = f" for {self.seconds:.1f} s" if self.seconds else ""
        after = f" after {self.mark!r}" if self.mark else ""
        cpu = f" to {self.share:.0%} of a CPU" if self.kind == "starve" and self.robot is not None \
            else ""
        return f"{self.kind} {target}{cpu} at {self.at:.1f} s{after}{span}"


@dataclass(frozen=True)
class Trial:
    index: int
    seed: int
    world: str
    algo: str
    robots: int
    scenario: str
    faults: tuple[Fault, ...] = ()
    messages: str = ""  # a bus.faults spec for every agent, "" for none

    @property
    def killed(self) -> set[int]:
        """Robots that are meant to die (killed, or hung past the death timeout)."""
        return {f.robot for f in self.faults if f.robot is not None
                and (f.kind in COVERAGE_FAULTS
                     or (f.kind == "hang" and f.seconds >= DEATH_HANG_S))}

    @property
    def cut_off(self) -> set[int]:
        """Robots a fault leaves unreachable past the lease (a partition, or a frozen router
        for every robot, of DEATH_HANG_S or more): declaring one of them dead is the
        liveliness token doing its job, as after a long hang; it need not happen, since
        the router may keep a session whose keep-alives were only late."""
        robots: set[int] = set()
        for f in self.faults:
            if f.seconds < DEATH_HANG_S:
                continue
            if f.kind == "partition" and f.robot is not None:
                robots.add(f.robot)
            elif f.kind == "router-freeze":
                robots.update(range(self.robots))
        return robots - self.killed

    def describe(self) -> str:
        parts = [f.describe() for f in self.faults]
        if self.messages:
            parts.append(f"messages {self.messages}")
        return "; ".join(parts) or "no faults"

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Campaign:
    """The options a campaign's trials are drawn from."""

    seed: int = 0
    worlds: tuple[str, ...] = ("example",)
    algos: tuple[str, ...] = GRID_FLEET
    sizes: tuple[int, ...] = (2, 3, 4)
    scenarios: tuple[str, ...] = SCENARIOS
    extra: dict[str, str] = field(default_factory=dict)


LONG_HANG_S = 4.0  # longer than the agents' death timeout (3 s by default)
# A process stopped (or cut off) this long loses its liveliness token (~0.75 x the 1 s
# Zenoh lease): declared dead by design, so not a false suspicion.
DEATH_HANG_S = 0.75


def make_trial(campaign: Campaign, index: int) -> Trial:
    """Trial ``index`` of ``campaign`` (the same every time)."""
    rng = random.Random(f"{campaign.seed}/{index}")
    world = rng.choice(campaign.worlds)
    algo = rng.choice(campaign.algos)
    k = rng.choice(campaign.sizes)
    scenario = campaign.scenarios[index % len(campaign.scenarios)]
    seed = rng.randrange(1 << 16)
    victims = rng.sample(range(k), k)
    faults: list[Fault] = []
    messages = ""
    if scenario == "early-kill":  # before or while announcing its start
        faults.append(Fault("kill", round(rng.uniform(0.3, 1.8), 2), victims[0]))
    elif scenario == "kill":
        faults.append(Fault("kill", round(rng.uniform(0.5, 6.0), 2), victims[0]))
    elif scenario == "kills":  # up to k - 1, from start-up on
        for robot in victims[:rng.randint(1, max(1, k - 1))]:
            faults.append(Fault("kill", round(rng.uniform(0.3, 6.0), 2), robot))
    elif scenario == "hang":
        faults.append(Fault("hang", round(rng.uniform(1.0, 5.0), 2), victims[0],
                            round(rng.uniform(0.1, 1.5), 2)))
    elif scenario == "long-hang":
        faults.append(Fault("hang", round(rng.uniform(1.0, 4.0), 2), victims[0],
                            round(rng.uniform(LONG_HANG_S, LONG_HANG_S + 2.0), 2)))
    elif scenario == "loss":
        messages = f"seed={seed};{LOSS_SPEC}"
    elif scenario == "router-restart":
        faults.append(Fault("router-kill", round(rng.uniform(1.0, 5.0), 2), None,
                            round(rng.uniform(0.3, 1.5), 2)))
    elif scenario == "router-freeze":
        faults.append(Fault("router-freeze", round(rng.uniform(1.0, 5.0), 2), None,
                            round(rng.uniform(0.3, 1.0), 2)))
    elif scenario == "partition":
        faults.append(Fault("partition", round(rng.uniform(1.5, 5.0), 2), victims[0],
                            round(rng.uniform(0.3, 2.0), 2)))
    elif scenario == "starve":
        faults.append(Fault("starve", round(rng.uniform(0.5, 4.0), 2), victims[0],
                            round(rng.uniform(1.0, 4.0), 2),
                            share=round(rng.uniform(0.05, 0.3), 2)))
    elif scenario == "starve-host":
        faults.append(Fault("starve", round(rng.uniform(0.5, 4.0), 2), None,
                            round(rng.uniform(1.0, 4.0), 2)))
    elif scenario == "mixed":
        faults.append(Fault("kill", round(rng.uniform(0.3, 6.0), 2), victims[0]))
        if k > 2:
            faults.append(Fault("hang", round(rng.uniform(1.0, 5.0), 2), victims[1],
                                round(rng.uniform(0.3, 1.5), 2)))
        messages = f"seed={seed};{LOSS_SPEC}"
    elif scenario == "late-death":  # at 20-90 % coverage, the process or its body
        kind, percent = rng.choice(COVERAGE_FAULTS), round(rng.uniform(20.0, 90.0), 1)
        # a robot with work left then, where the plan tells (deploy/chaos/victims.py)
        busy = busy_at(world, algo, k, seed, percent) if k > 1 else ()
        faults.append(Fault(kind, 0.0, rng.choice(busy) if busy else victims[0],
                            percent=percent))
    if k == 1:  # the one robot must live: faults that kill it prove nothing
        faults = [f for f in faults if f.kind not in COVERAGE_FAULTS and
                  not (f.kind == "hang" and f.seconds >= DEATH_HANG_S)]
    return Trial(index, seed, world, algo, k, scenario,
                 tuple(sorted(faults, key=lambda f: f.at)), messages)
