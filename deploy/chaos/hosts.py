"""Hosts made of network namespaces, for fleets spread over several machines on one.

Each host is a namespace with its own loopback and one veth link to a hub namespace that
bridges them (a switch); a host's address is 10.201.0.<i+1>/24. Cutting a host takes its
link down (a pulled cable), healing brings it back: the address and the route come back
with it. The hub and every host are removed on exit, also after a failure.

Only namespaces this module creates are touched; their names carry the creator's PID so two
runs never share one. Needs root and iproute2 (`ip netns`): :func:`hosts_problem` says why
not.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

SUBNET = "10.201.0"
ZENOH_PORT = 7447


class HostsError(RuntimeError):
    """A namespace, link or address could not be made."""


@dataclass(frozen=True)
class Host:
    name: str  # the namespace
    address: str
    link: str  # the host's end of its veth pair

    def run(self, argv: list[str]) -> list[str]:
        """``argv`` run inside this host."""
        return ["ip", "netns", "exec", self.name, *argv]

    @property
    def endpoint(self) -> str:
        return f"tcp/{self.address}:{ZENOH_PORT}"

    @property
    def tls_endpoint(self) -> str:
        return f"tls/{self.address}:{ZENOH_PORT}"

    def cut(self) -> None:
        _ip("-n", self.name, "link", "set", self.link, "down")

    def heal(self) -> None:
        _ip("-n", self.name, "link", "set", self.link, "up")


def hosts_problem() -> str | None:
    """Why namespaces cannot be made here, or None."""
    if shutil.which("ip") is None:
        return "iproute2 is not installed (apt-get install -y iproute2)"
    if os.geteuid() != 0:
        return "making network namespaces needs root"
    probe = f"mstc-probe-{os.getpid()}"
    made = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True,
                          check=False)
    if made.returncode != 0:
        return f"ip netns add fails: {made.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True, check=False)
    return None


@contextmanager
def hosts(count: int, prefix: str = "mstc") -> Iterator[list[Host]]:
    """``count`` hosts on one switch; all removed when the block ends."""
    tag = f"{prefix}{os.getpid()}"
    hub = f"{tag}-hub"
    made: list[str] = []
    try:
        _ip("netns", "add", hub)
        made.append(hub)
        _ip("-n", hub, "link", "add", "br0", "type", "bridge")
        _ip("-n", hub, "link", "set", "br0", "up")
        found: list[Host] = []
        for index in range(count):
            host = Host(f"{tag}-h{index}", f"{SUBNET}.{index + 1}", f"eth{index}")
            _ip("netns", "add", host.name)
            made.append(host.name)
            port = f"{tag}p{index}"[-15:]  # interface names have at most 15 characters
            _ip("link", "add", host.link + tag[-6:], "type", "veth", "peer", "name", port)
            _ip("link", "set", host.link + tag[-6:], "netns", host.name)
            _ip("-n", host.name, "link", "set", host.link + tag[-6:], "name", host.link)
            _ip("link", "set", port, "netns", hub)
            _ip("-n", hub, "link", "set", port, "master", "br0")
            _ip("-n", hub, "link", "set", port, "up")
            _ip("-n", host.name, "addr", "add", f"{host.address}/24", "dev", host.link)
            _ip("-n", host.name, "link", "set", "lo", "up")
            host.heal()
            found.append(host)
        yield found
    finally:
        for name in reversed(made):  # deleting a namespace deletes its links too
            subprocess.run(["ip", "netns", "del", name], capture_output=True, check=False)


def _ip(*args: str) -> None:
    done = subprocess.run(["ip", *args], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise HostsError(f"ip {' '.join(args)}: {done.stderr.strip()}")
