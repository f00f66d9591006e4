"""Where the daemon for this environment lives, and the checks that keep it private.

One daemon serves one ROS environment (the variables that decide what a participant
discovers and how) and one installation of ContextROS: a command run with another
`ROS_DOMAIN_ID`, another RMW or another venv reaches another daemon. Its socket, lock and
log sit in a directory only its user can enter.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
import sys
from pathlib import Path

import contextros

# The variables that change what a ROS participant discovers, or how it talks.
_ROS_PREFIXES = (
    "ROS_",
    "RMW_",
    "FASTDDS_",
    "FASTRTPS_",
    "SKIP_DEFAULT_XML_FILE",
    "CYCLONEDDS_",
    "ZENOH_",
    "NDDS_",
    "CONNEXTDDS_",
    "GURUMDDS_",
)
# Fast DDS also reads this profile from the working directory (the daemon keeps the working
# directory of the command that started it).
_CWD_PROFILE = "DEFAULT_FASTDDS_PROFILES.xml"
# A socket's path is at most this long (sockaddr_un's sun_path, less its terminator).
MAX_SOCKET_PATH = 107
# (Not LD_LIBRARY_PATH: the ROS wheels' bootstrapper rewrites it, in no fixed order, in
# every interpreter; the interpreter and the package's path already name the installation.)
_OTHER_VARIABLES = ("AMENT_PREFIX_PATH", "PYTHONPATH")
# The daemon's own code: a change starts a new daemon instead of reusing a stale one.
_CODE = ("cli/daemon/server.py", "cli/daemon/wire.py", "ros/client.py", "ros/messages.py")
RUNTIME_VARIABLE = "CONTEXTROS_RUNTIME_DIR"


class PlaceError(Exception):
    """The daemon's directory cannot be trusted or created."""


class DaemonPlace:
    """The daemon's socket, lock and log (a plain class: `dataclasses` would add 10 ms to
    every command's imports)."""

    def __init__(self, directory: Path, key: str) -> None:
        self.directory = directory
        self.key = key

    def _file(self, suffix: str) -> Path:
        return self.directory / f"daemon-{self.key}.{suffix}"

    @property
    def socket(self) -> Path:
        return self._file("sock")

    @property
    def lock(self) -> Path:
        return self._file("lock")

    @property
    def log(self) -> Path:
        return self._file("log")

    @property
    def pid_file(self) -> Path:
        """The pid of the daemon a command started last (until it holds the lock)."""
        return self._file("pid")


def environment_key(environ: dict[str, str] | os._Environ[str] = os.environ) -> str:
    """A short digest of what makes one daemon unfit for another environment."""
    package = Path(contextros.__file__).resolve().parent
    parts = [contextros.__version__, str(package), sys.executable]
    for relative in _CODE:
        try:
            parts.append(f"{relative}:{(package / relative).stat().st_mtime_ns}")
        except OSError:
            parts.append(f"{relative}:-")
    parts += sorted(
        f"{name}={value}"
        for name, value in environ.items()
        if name.startswith(_ROS_PREFIXES) or name in _OTHER_VARIABLES
    )
    # The network the participant would join: a command in another network namespace (`ip
    # netns exec`, a container sharing /tmp) reaches a daemon of its own.
    with contextlib.suppress(OSError):
        parts.append(f"netns={os.readlink('/proc/self/ns/net')}")
    with contextlib.suppress(OSError):  # none here is the common case
        profile = Path(_CWD_PROFILE).resolve()
        parts.append(f"{profile}:{profile.stat().st_mtime_ns}")
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()[:16]


def runtime_directory(environ: dict[str, str] | os._Environ[str] = os.environ) -> Path:
    """$CONTEXTROS_RUNTIME_DIR, else $XDG_RUNTIME_DIR/contextros, else /tmp/contextros-UID."""
    if chosen := environ.get(RUNTIME_VARIABLE):
        return Path(chosen)
    xdg = environ.get("XDG_RUNTIME_DIR")
    if xdg and _owned(Path(xdg)):  # not a directory kept by `sudo -E` from another user
        return Path(xdg) / "contextros"
    return Path("/tmp") / f"contextros-{os.getuid()}"


def _owned(path: Path) -> bool:
    try:
        return path.stat().st_uid == os.getuid()
    except OSError:
        return False


def private_directory(path: Path) -> Path:
    """Create `path` (mode 0700) or check that it is this user's and no one else's."""
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = path.lstat()
    except OSError as error:
        raise PlaceError(f"cannot create the daemon's directory {path}: {error}") from error
    if not stat.S_ISDIR(info.st_mode):
        raise PlaceError(f"{path} is not a directory")
    if info.st_uid != os.getuid():
        raise PlaceError(f"{path} belongs to uid {info.st_uid}, not to this user")
    if info.st_mode & 0o077:
        raise PlaceError(
            f"{path} is open to other users (mode {stat.S_IMODE(info.st_mode):o}); it must be 0700"
        )
    return path


def daemon_place(environ: dict[str, str] | os._Environ[str] = os.environ) -> DaemonPlace:
    """The daemon for this environment; PlaceError if its directory is not private, or
    too deep for a socket."""
    place = DaemonPlace(runtime_directory(environ), environment_key(environ))
    if len(os.fsencode(place.socket)) > MAX_SOCKET_PATH:
        raise PlaceError(
            f"{place.directory} is too long a path for the daemon's socket (at most "
            f"{MAX_SOCKET_PATH} bytes with its name); set {RUNTIME_VARIABLE} to a shorter one"
        )
    private_directory(place.directory)
    return place


def places(directory: Path) -> list[DaemonPlace]:
    """Every daemon with a socket in `directory` (whatever its environment)."""
    return [
        DaemonPlace(directory, path.stem.removeprefix("daemon-"))
        for path in sorted(directory.glob("daemon-*.sock"))
    ]
