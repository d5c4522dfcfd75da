"""Cutting one robot off from its router on loopback, and healing the cut.

A cut has two parts:

- **Its connections.** iptables DROPs, on ``lo``, of the packets of the robot's TCP
  connections to the router, matched by their local ports (:func:`tcp_ports`).
- **Its reconnections.** Zenoh's client gives up a silent link after its lease (1 s
  here) and connects again from a new port, which the port rules do not match. Without
  this part a partition of 2 s held for only about 1 s: on 2026-12-06 a robot cut off
  for 4 s had a new connection 1.2 s into the cut.
  - So the robot's process is moved for the cut into a cgroup (v2) of its own.
  - One iptables rule (the ``cgroup`` match) refuses every connection that sockets of
    that group open to the router's port.
  - A socket stays in the cgroup of the process that made it. The move therefore
    catches only sockets made afterwards; the old connection stays the port rules'.
  - It is refused with a TCP reset, not dropped. The client then retries at its own pace
    (bus.config's ``connect/retry``: at most a second apart). A dropped attempt would be
    retried by the kernel's SYN back-off instead (1 s, then 2 s, 4 s, ...), which could
    keep the robot cut off for seconds after the heal.

Where the cgroup part cannot be made (no cgroup v2 hierarchy, no ``cgroup`` match), the cut
is its first part alone and the trial's record says so.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
from pathlib import Path

GROUP_PREFIX = "mstc-partition-"


class InjectionError(RuntimeError):
    """A fault could not be carried out (the trial would run without it unseen)."""


def partition_problem() -> str | None:
    """Why partitions cannot be made here, or None."""
    if shutil.which("iptables") is None:
        return "iptables is not installed (apt-get install -y iptables)"
    probe = subprocess.run(["iptables", "-S", "INPUT"], capture_output=True, text=True,
                           check=False)
    if probe.returncode != 0:
        return f"iptables cannot be used: {probe.stderr.strip() or probe.returncode}"
    return None


def tcp_ports(pid: int, remote_port: int) -> list[int]:
    """Local ports of process ``pid``'s TCP connections to ``remote_port`` (loopback)."""
    inodes: set[str] = set()
    with contextlib.suppress(OSError):
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            with contextlib.suppress(OSError):
                target = os.readlink(fd)
                if target.startswith("socket:["):
                    inodes.add(target[8:-1])
    ports = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with contextlib.suppress(OSError):
            for line in Path(table).read_text().splitlines()[1:]:
                fields = line.split()
                local, remote, inode = fields[1], fields[2], fields[9]
                if inode in inodes and int(remote.rsplit(":", 1)[1], 16) == remote_port:
                    ports.append(int(local.rsplit(":", 1)[1], 16))
    return sorted(set(ports))


class Cut:
    """Robot process ``pid`` cut off from the router on ``router_port``: :meth:`make`,
    then :meth:`heal` (always, also when making failed half-way)."""

    def __init__(self, pid: int, router_port: int) -> None:
        self.pid = pid
        self.router_port = router_port
        self.ports: list[int] = []  # local ports whose rules are in
        self.reconnects_blocked = ""  # why not, when they are not ("" once they are)
        self._group = f"{GROUP_PREFIX}{pid}"
        self._root: Path | None = None  # the cgroup v2 mount, once the group is made
        self._home = "/"
        self._group_rule = False

    def make(self, ports: list[int]) -> None:
        """Block new connections (or note why not), then drop those of ``ports``;
        InjectionError if a port rule cannot be put in."""
        try:
            self._block_reconnects()
        except InjectionError as error:
            self.reconnects_blocked = str(error)
        for port in ports:
            _port_rules("-I", port)
            self.ports.append(port)

    def heal(self) -> str:
        """Take every rule out and move the process home; what failed, as a note for the
        trial's record ("" if nothing)."""
        failed = []
        for port in self.ports:
            try:
                _port_rules("-D", port)
            except InjectionError as error:
                failed.append(str(error))
        self.ports = []
        failed.extend(self._unblock_reconnects())
        return f"; heal failed: {'; '.join(failed)}" if failed else ""

    def _block_reconnects(self) -> None:
        root = cgroup2_root()
        if root is None:
            raise InjectionError("no cgroup v2 hierarchy is mounted")
        self._home = _group_of(self.pid)
        try:
            (root / self._group).mkdir(exist_ok=True)
            self._root = root
            (root / self._group / "cgroup.procs").write_text(str(self.pid))
        except OSError as error:
            self._unblock_reconnects()
            raise InjectionError(f"cannot move process {self.pid} into a cgroup of its "
                                 f"own: {error}") from error
        result = _group_rule("-I", self._group, self.router_port)
        if result.returncode != 0:
            self._unblock_reconnects()
            raise InjectionError("iptables cgroup match: "
                                 f"{result.stderr.strip() or result.returncode}")
        self._group_rule = True

    def _unblock_reconnects(self) -> list[str]:
        failed = []
        if self._group_rule:
            result = _group_rule("-D", self._group, self.router_port)
            if result.returncode != 0:
                failed.append(f"iptables -D cgroup rule: "
                              f"{result.stderr.strip() or result.returncode}")
            self._group_rule = False
        if self._root is not None:
            home = self._root / self._home.lstrip("/") / "cgroup.procs"
            try:
                home.write_text(str(self.pid))
            except OSError as error:
                if Path(f"/proc/{self.pid}").exists():  # a process that ended moves nowhere
                    failed.append(f"cannot move process {self.pid} back: {error}")
            try:
                (self._root / self._group).rmdir()
            except FileNotFoundError:
                pass
            except OSError as error:
                failed.append(f"cannot remove cgroup {self._group}: {error}")
            self._root = None
        return failed


def cgroup2_root() -> Path | None:
    """Where the cgroup v2 hierarchy is mounted, or None."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/mounts").read_text().splitlines():
            fields = line.split()
            if len(fields) >= 3 and fields[2] == "cgroup2":
                return Path(fields[1])
    return None


def _group_of(pid: int) -> str:
    """The cgroup v2 path of process ``pid`` (``/`` for the root)."""
    try:
        for line in Path(f"/proc/{pid}/cgroup").read_text().splitlines():
            if line.startswith("0::"):
                return line[3:] or "/"
    except OSError as error:
        raise InjectionError(f"cannot read the cgroup of process {pid}: {error}") from error
    return "/"


def _group_rule(action: str, group: str, port: int) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["iptables", "-w", "5", action, "OUTPUT", "-o", "lo", "-p", "tcp",
                           "--dport", str(port), "-m", "cgroup", "--path", group,
                           "-j", "REJECT", "--reject-with", "tcp-reset"],
                          capture_output=True, text=True, check=False)


def _port_rule(action: str, direction: str, port: int) -> subprocess.CompletedProcess[str]:
    # -w: trials running side by side take the xtables lock in turn instead of failing.
    return subprocess.run(["iptables", "-w", "5", action, "INPUT", "-i", "lo", "-p", "tcp",
                           direction, str(port), "-j", "DROP"],
                          capture_output=True, text=True, check=False)


def _port_rules(action: str, port: int) -> None:
    """Insert (-I) or delete (-D) the two DROP rules of one local port on lo."""
    done: list[str] = []
    for direction in ("--sport", "--dport"):
        result = _port_rule(action, direction, port)
        if result.returncode != 0:
            if action == "-I":  # no half partition left behind
                for undo in done:
                    _port_rule("-D", undo, port)
            raise InjectionError(f"iptables {action} port {port}: "
                                 f"{result.stderr.strip() or result.returncode}")
        done.append(direction)
