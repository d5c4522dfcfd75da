"""Per-mission credentials: one user name and random password per role, kept in a JSON file
of mode 0600 (in the run directory of ``mstc up``, or wherever an operator put it).

The file of a whole mission is what the router needs; a process needs only its own role's
entry, so :meth:`Credentials.only` makes the file to copy onto a robot's host.
"""

from __future__ import annotations

import json
import os
import secrets
import stat
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bus.errors import ConfigError
from bus.keys import check_mission
from bus.security.roles import Role, mission_roles, parse_role

FORMAT = "mstc-credentials"
VERSION = 1
CREDENTIALS_FILE = "credentials.json"  # its name inside a run directory
ENV_CREDENTIALS = "MSTC_CREDENTIALS"
ENV_ROLE = "MSTC_ROLE"
PASSWORD_BYTES = 24  # 192 random bits per password


@dataclass(frozen=True)
class Credentials:
    mission: str
    passwords: Mapping[str, str] = field(default_factory=dict)  # role name -> password

    def __post_init__(self) -> None:
        try:
            check_mission(self.mission)
        except ValueError as error:
            raise ConfigError(str(error)) from error
        for name, password in self.passwords.items():
            parse_role(name)
            if not isinstance(password, str) or not password or ":" in password \
                    or "\n" in password:
                raise ConfigError(f"credentials of {name}: a password is one line without ':'")

    @property
    def roles(self) -> tuple[Role, ...]:
        return tuple(sorted((parse_role(name) for name in self.passwords),
                            key=lambda role: role.rank))

    @property
    def robots(self) -> tuple[int, ...]:
        return tuple(r.robot for r in self.roles if r.robot is not None)

    def password(self, role: Role) -> str:
        password = self.passwords.get(role.name)
        if password is None:
            raise ConfigError(f"the credentials of mission {self.mission!r} have no entry "
                              f"for role {role.name}")
        return password

    def only(self, role: Role) -> Credentials:
        """The credentials of one role alone (what to install on that role's host)."""
        return Credentials(self.mission, {role.name: self.password(role)})

    def rotated(self) -> Credentials:
        """The same roles with fresh passwords."""
        return Credentials(self.mission, {name: _new_password() for name in self.passwords})

    def dictionary(self) -> str:
        """The router's user:password dictionary (Zenoh's usrpwd dictionary_file format)."""
        return "".join(f"{name}:{pw}\n" for name, pw in sorted(self.passwords.items()))

    def to_json(self) -> str:
        return json.dumps({"format": FORMAT, "version": VERSION, "mission": self.mission,
                           "users": dict(sorted(self.passwords.items()))}, indent=2) + "\n"

    def save(self, path: Path) -> None:
        """Write the file readable by its owner only (created 0600, never wider)."""
        write_private(path, self.to_json())


def _new_password() -> str:
    return secrets.token_urlsafe(PASSWORD_BYTES)


def generate(mission: str, robots: int) -> Credentials:
    """Fresh credentials for every role of a mission of robots 0..robots-1."""
    return Credentials(mission, {role.name: _new_password() for role in mission_roles(robots)})


def write_private(path: Path, text: str) -> None:
    """Create or replace ``path`` with mode 0600 (the mode is set before any byte lands)."""
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        with os.fdopen(fd, "w") as out:
            out.write(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def load(path: Path) -> Credentials:
    """Read a credentials file; ConfigError (one line) if missing, malformed or readable by
    others than its owner."""
    try:
        mode = path.stat().st_mode
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(f"credentials file {path} does not exist") from None
    except OSError as error:
        raise ConfigError(f"cannot read credentials file {path}: {error.strerror}") from error
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ConfigError(f"credentials file {path} is readable by others: chmod 600 {path}")
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as error:
        raise ConfigError(f"credentials file {path} is not JSON: {error}") from error
    if not isinstance(raw, dict) or raw.get("format") != FORMAT \
            or raw.get("version") != VERSION:
        raise ConfigError(f"{path} is not a mstc credentials file (format {FORMAT} "
                          f"version {VERSION})")
    users, mission = raw.get("users"), raw.get("mission")
    if not isinstance(users, dict) or not isinstance(mission, str):
        raise ConfigError(f"credentials file {path} needs 'mission' and 'users'")
    return Credentials(mission, {str(k): v for k, v in users.items()})


def locate(explicit: Path | None, run_dir: Path | None,
           env: Mapping[str, str] | None = None) -> Path | None:
    """Where a tool finds its credentials: --credentials, else $MSTC_CREDENTIALS, else the
    run directory's file if there is one; None when there are none (an insecure run)."""
    env = os.environ if env is None else env
    if explicit is not None:
        return explicit
    if env.get(ENV_CREDENTIALS):
        return Path(env[ENV_CREDENTIALS])
    if run_dir is not None and (run_dir / CREDENTIALS_FILE).is_file():
        return run_dir / CREDENTIALS_FILE
    return None
