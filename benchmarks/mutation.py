"""Mutation testing of the core modules: a small AST mutator, plus issue 15's named mutants.

    .venv/bin/python benchmarks/mutation.py                       # every module, 20 mutants each
    .venv/bin/python benchmarks/mutation.py --max 40 --seed 1     # more, another sample
    .venv/bin/python benchmarks/mutation.py --module bus/liveness.py
    .venv/bin/python benchmarks/mutation.py --named               # issue 15's table only
    .venv/bin/python benchmarks/mutation.py --named --with-fleet  # those with real processes too
    .venv/bin/python benchmarks/mutation.py --module deploy/supervisor.py --with-fleet

Each mutant is written into a scratch copy of the repository (the worktree is never touched)
and the module's fast tests run there with ``python -m pytest -x`` (the copy comes first on
sys.path; the editable install's finder only sees what the path misses). A mutant is killed
when the tests fail or time out, survives when they pass. Operators: comparison flips
(< <=, > >=, == !=, in / not in, is / is not), + / -, and / or, dropping a ``not``, an int
constant + 1, True / False, a call statement replaced by ``pass`` (wiring removed).

Why not mutmut or cosmic-ray: mutmut 3 copies the tree and runs the whole suite for its
statistics, real-process fleet tests included (hours on a loaded 2-core machine), and
neither lets one pick the tests per module as simply; this script is small enough to read.
Results go to docs/testing.md by hand, with the command that produced them.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NO_TESTS = 5  # pytest's exit code when nothing was selected: a mistake here, not a kill
FAST = ["-x", "-q", "-p", "no:randomly", "-p", "no:cacheprovider",
        "--hypothesis-profile", "quick", "-m", "not slow and not integration"]

# module -> the fast tests meant to guard it
MODULES: dict[str, list[str]] = {
    "planner/allocation/optimal.py": ["tests/test_allocation_opt.py",
                                      "tests/test_allocation_plan.py"],
    "planner/offline/machine.py": ["tests/test_takeover_oracle.py", "tests/test_takeover.py",
                                   "tests/test_agent_units.py",
                                   "tests/test_agent_knowledge.py"],
    "bus/liveness.py": ["tests/test_bus_liveness.py", "tests/test_agent_knowledge.py"],
    "agent/offline/peers.py": ["tests/test_agent_units.py", "tests/test_agent_knowledge.py"],
    "deploy/supervisor.py": ["tests/test_kill_schedule.py", "tests/test_fleet_unit.py"],
    "deploy/settings.py": ["tests/test_kill_schedule.py", "tests/test_fleet_unit.py"],
    "deploy/fleet_timing.py": ["tests/test_fleet_scale.py", "tests/test_autogroup.py",
                               "tests/test_fleet_unit.py"],
    "planner/ormstc/machine.py": ["tests/test_ormstc_conflicts.py", "tests/test_ormstc_sim.py",
                                  "tests/test_ormstc_claims.py",
                                  "tests/test_ormstc_walk.py"],
}

# With --with-fleet, the tests with real processes that guard a module as well.
FLEET_TESTS: dict[str, list[str]] = {
    "deploy/supervisor.py": ["tests/test_up_negative.py"],
    "bus/liveness.py": ["tests/test_bus_liveness_service.py"],
}


@dataclass(frozen=True)
class Named:
    """One mutation of issue 15's table: replace ``old`` (exactly once) by ``new``."""

    what: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]
    fleet: bool = False  # its guard starts real processes (run with --with-fleet)


NAMED = [
    Named("optimal allocation chain check >= -> >", "planner/allocation/optimal.py",
          "(a + b0 >= last)", "(a + b0 > last)", ("tests/test_allocation_opt.py",)),
    Named("drop the last takeover step", "planner/offline/machine.py",
          "range(1, distance + 1)", "range(1, distance)",
          ("tests/test_takeover_oracle.py", "tests/test_takeover.py")),
    Named("skip the bus overflow drop counter", "bus/inbox.py",
          "            self._on_overflow(key)", "            pass",
          ("tests/test_bus_bridge.py",), fleet=True),
    Named("lower bound off by one", "planner/allocation/optimal.py",
          "total = (sum(gaps) - 0.5)", "total = (sum(gaps) + 0.5)",
          ("tests/test_allocation_opt.py",)),
    Named("death notices after planning ignored by the peer table", "agent/offline/peers.py",
          "            self.machine.on_dead(notice.robot)\n", "            pass\n",
          ("tests/test_agent_knowledge.py", "tests/test_agent_units.py")),
    Named("the agent watches its predecessor instead of its successor",
          "planner/offline/machine.py", "zip(order, order[1:] + order[:1], strict=True)",
          "zip(order, order[-1:] + order[:-1], strict=True)",
          ("tests/test_takeover_oracle.py", "tests/test_takeover.py")),
    Named("takeover walks to the end of the dead robot's region",
          "planner/offline/machine.py", "offsets[open_offsets[-1]]", "offsets[-1]",
          ("tests/test_takeover_oracle.py",)),
    Named("mstc up --kill R@SECONDS never fires", "deploy/settings.py",
          "return ((self.seconds is not None and elapsed is not None and elapsed >= self.seconds)",
          "return ((False)", ("tests/test_kill_schedule.py",)),
    Named("mstc up's stall timeout never triggers", "deploy/launch.py",
          "elif started is not None and now - t.last_progress > s.stall_timeout:",
          "elif False:", ("tests/test_up_negative.py::test_up_exits_1_when_the_mission_stalls",),
          fleet=True),
    Named("no state refresh before a takeover", "agent/offline/runner.py",
          "                self._refreshed = time.monotonic()\n"
          "                await self._refresh()\n            action",
          "                pass\n            action", ("tests/test_agent_knowledge.py",)),
    Named("liveness stall wiring removed", "bus/liveness.py",
          "            self.detector.on_local_stall(now)", "            pass",
          ("tests/test_agent_knowledge.py", "tests/test_bus_liveness.py")),
]

_FLIPS: dict[type[ast.cmpop], type[ast.cmpop]] = {
    ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq, ast.In: ast.NotIn, ast.NotIn: ast.In, ast.Is: ast.IsNot,
    ast.IsNot: ast.Is}


class Mutator(ast.NodeTransformer):
    """Counts the mutation sites; when ``target`` is set, applies the one with that number."""

    def __init__(self, target: int | None = None) -> None:
        self.target = target
        self.sites: list[str] = []
        self.applied = ""

    def _site(self, node: ast.AST, what: str) -> bool:
        number = len(self.sites)
        self.sites.append(f"line {getattr(node, 'lineno', '?')}: {what}")
        if number == self.target:
            self.applied = self.sites[-1]
            return True
        return False

    def visit_Compare(self, node: ast.Compare) -> ast.AST:
        self.generic_visit(node)
        for i, op in enumerate(node.ops):
            flipped = _FLIPS.get(type(op))
            if flipped and self._site(node, f"{type(op).__name__} -> {flipped.__name__}"):
                node.ops[i] = flipped()
        return node

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        swap = {ast.Add: ast.Sub, ast.Sub: ast.Add}.get(type(node.op))
        if swap and self._site(node, f"{type(node.op).__name__} -> {swap.__name__}"):
            node.op = swap()
        return node

    def visit_BoolOp(self, node: ast.BoolOp) -> ast.AST:
        self.generic_visit(node)
        swap = ast.Or if isinstance(node.op, ast.And) else ast.And
        if self._site(node, f"{type(node.op).__name__} -> {swap.__name__}"):
            node.op = swap()
        return node

    def visit_UnaryOp(self, node: ast.UnaryOp) -> ast.AST:
        self.generic_visit(node)
        if isinstance(node.op, ast.Not) and self._site(node, "drop not"):
            return node.operand
        return node

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        if isinstance(node.value, bool):
            if self._site(node, f"{node.value} -> {not node.value}"):
                return ast.copy_location(ast.Constant(not node.value), node)
        elif isinstance(node.value, int) and self._site(node, f"{node.value} -> "
                                                               f"{node.value + 1}"):
            return ast.copy_location(ast.Constant(node.value + 1), node)
        return node

    def visit_Expr(self, node: ast.Expr) -> ast.AST:
        self.generic_visit(node)
        call = node.value.value if isinstance(node.value, ast.Await) else node.value
        if isinstance(call, ast.Call) and self._site(node, "call statement -> pass"):
            return ast.copy_location(ast.Pass(), node)
        return node

    # Annotations are not behaviour.
    def visit_AnnAssign(self, node: ast.AnnAssign) -> ast.AST:
        if node.value is not None:
            node.value = self.visit(node.value)
        return node

    def visit_arg(self, node: ast.arg) -> ast.AST:
        return node


def mutants(source: str) -> Iterator[tuple[int, str, str]]:
    """(number, description, mutated source) of every site of ``source``."""
    count = Mutator()
    count.visit(ast.parse(source))
    for number in range(len(count.sites)):
        mutator = Mutator(number)
        tree = mutator.visit(ast.parse(source))
        yield number, mutator.applied, ast.unparse(ast.fix_missing_locations(tree))


def scratch_copy() -> Path:
    target = Path(tempfile.mkdtemp(prefix="mstc-mutation-"))
    for name in ("agent", "bus", "deploy", "planner", "simhw", "tests", "pyproject.toml"):
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, target / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(src, target / name)
    return target


def kill_leftovers(copy: Path) -> int:
    """SIGKILL every process still running the mutant copy (found by the PYTHONPATH it
    inherited): a timed-out fleet test leaves `mstc up` and its agents, each in a session of
    its own, which neither killing pytest nor its process group reaches."""
    mark, killed = f"PYTHONPATH={copy}".encode(), 0
    for proc_dir in Path("/proc").iterdir():
        if not proc_dir.name.isdigit() or int(proc_dir.name) == os.getpid():
            continue
        try:
            inherited = (proc_dir / "environ").read_bytes().split(b"\0")
        except OSError:  # gone already, or not ours to read
            continue
        if mark in inherited:
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(proc_dir.name), signal.SIGKILL)
                killed += 1
    return killed


def run_tests(copy: Path, tests: list[str] | tuple[str, ...], timeout: float,
              fast: bool = True) -> tuple[bool, str]:
    """(killed, last line of pytest's output); ``fast=False`` lets marked tests run too."""
    args = FAST if fast else FAST[:-2]
    env = {**os.environ, "PYTHONPATH": str(copy), "PYTHONDONTWRITEBYTECODE": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "pytest", *args, *tests], cwd=copy,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return True, "timed out"
    finally:
        kill_leftovers(copy)
    lines = [line for line in stdout.splitlines() if line.strip()]
    last = lines[-1] if lines else stderr.strip()[-200:]
    if proc.returncode == NO_TESTS:
        raise RuntimeError(f"no test ran: {' '.join(tests)} ({last})")
    return proc.returncode != 0, last


def mutate_modules(modules: list[str], limit: int, seed: int, timeout: float,
                   with_fleet: bool = False) -> None:
    copy = scratch_copy()
    try:
        for module in modules:
            path = copy / module
            original = path.read_text()
            every = list(mutants(original))
            picked = sorted(random.Random(f"{seed}:{module}").sample(every,
                                                                     min(limit, len(every))))
            killed, survivors = 0, []
            started = time.monotonic()
            tests = MODULES[module] + (FLEET_TESTS.get(module, []) if with_fleet else [])
            fast = not (with_fleet and module in FLEET_TESTS)
            ok, why = run_tests(copy, tests, timeout, fast)
            if ok:
                print(f"{module}: its tests fail unmutated ({why}); skipped")
                continue
            for _number, what, source in picked:
                path.write_text(source)
                dead, why = run_tests(copy, tests, timeout, fast)
                path.write_text(original)
                killed += dead
                if not dead:
                    survivors.append(what)
                print(f"  {'killed' if dead else 'survived'}: {what} ({why})", flush=True)
            print(f"{module}: {killed}/{len(picked)} killed of {len(every)} sites "
                  f"({time.monotonic() - started:.0f} s)")
            for what in survivors:
                print(f"    survived: {what}")
    finally:
        shutil.rmtree(copy)


def run_named(with_fleet: bool, timeout: float, only: str = "") -> None:
    copy = scratch_copy()
    try:
        for m in (m for m in NAMED if only in m.what):
            if m.fleet and not with_fleet:
                print(f"- {m.what}: skipped (needs --with-fleet)")
                continue
            path = copy / m.path
            original = path.read_text()
            assert original.count(m.old) == 1, f"{m.path}: {m.old!r} not found exactly once"
            path.write_text(original.replace(m.old, m.new))
            dead, why = run_tests(copy, m.tests, timeout, fast=not m.fleet)
            path.write_text(original)
            print(f"- {m.what}: {'killed' if dead else 'SURVIVED'} by {' '.join(m.tests)} "
                  f"({why})")
    finally:
        shutil.rmtree(copy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--module", action="append", choices=sorted(MODULES), default=None)
    parser.add_argument("--max", type=int, default=20, help="mutants per module (sampled)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=300.0, help="per test run, seconds")
    parser.add_argument("--named", action="store_true", help="issue 15's table only")
    parser.add_argument("--with-fleet", action="store_true",
                        help="also the tests with real processes (named mutants, and the "
                             "modules of FLEET_TESTS)")
    parser.add_argument("--only", default="", metavar="TEXT",
                        help="the named mutants whose description contains TEXT")
    args = parser.parse_args()
    if args.named:
        run_named(args.with_fleet, args.timeout, args.only)
    else:
        mutate_modules(args.module or sorted(MODULES), args.max, args.seed, args.timeout,
                       args.with_fleet)


if __name__ == "__main__":
    main()
