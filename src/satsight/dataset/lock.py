"""One writer per dataset folder: an advisory lock file, ``DIR/.satsight-writer.lock``.

``generate`` (new, ``--resume``, ``--overwrite``) and ``merge`` (on ``--out``, and on the
shards with ``--move``) hold it while they write; ``validate``, ``stats`` and ``export``
only read and never take it. A second writer is refused with one line naming the holder.

The lock is ``fcntl.flock`` on the open lock file, not the file's existence (``O_EXCL``):
the kernel drops a flock when its process ends in any way (``kill -9`` included), so a
lock file left behind is stale by construction and needs no guess about whether a pid is
still alive (pids are reused; a pid on another machine cannot be looked up). The file's
text (pid, host, start time, command) is only for the messages. On Linux, NFS carries
flock as a POSIX lock to the server, so writers on other machines see it too; a stale file
written on another host is still refused (its run may be alive on a file system that does
not share locks) with how to remove it.
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import shlex
import socket
import sys
import time
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path

from satsight.errors import SatsightError

log = logging.getLogger(__name__)

LOCK_NAME = ".satsight-writer.lock"


def lock_path(folder: Path) -> Path:
    return Path(folder) / LOCK_NAME


def folder_entries(folder: Path) -> list[Path]:
    """The entries of ``folder`` other than its lock file (none when it does not exist)."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    return [p for p in folder.iterdir() if p.name != LOCK_NAME]


def this_command() -> str:
    """The command line of this process, as the user typed it (best effort)."""
    argv = list(sys.argv)
    if argv and Path(argv[0]).name in ("satsight", "__main__.py"):
        argv[0] = "satsight"
    return shlex.join(argv) if argv else "python"


@dataclass(frozen=True)
class LockHolder:
    """Who holds (or held) a dataset folder's lock."""

    pid: int
    host: str
    started: str
    command: str

    @classmethod
    def me(cls) -> LockHolder:
        started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        return cls(os.getpid(), socket.gethostname(), started, this_command())

    @classmethod
    def parse(cls, text: bytes) -> LockHolder | None:
        try:
            data = json.loads(text)
            return cls(int(data["pid"]), str(data["host"]), str(data["started"]),
                       str(data["command"]))  # fmt: skip
        except (ValueError, KeyError, TypeError):
            return None

    def text(self) -> bytes:
        document = {"pid": self.pid, "host": self.host, "started": self.started,
                    "command": self.command}  # fmt: skip
        return (json.dumps(document) + "\n").encode("utf-8")

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host}, since {self.started}: {self.command}"

    def alive_here(self) -> bool:
        """Whether this names a live process of this machine."""
        if self.host != socket.gethostname():
            return False
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True


def _read(fd: int) -> LockHolder | None:
    os.lseek(fd, 0, os.SEEK_SET)
    return LockHolder.parse(os.read(fd, 1 << 16))


def _read_holder(fd: int) -> LockHolder | None:
    """The holder named in a locked file: it writes its name just after locking, so an
    empty file is read again for up to a second."""
    for _ in range(20):
        if (holder := _read(fd)) is not None:
            return holder
        time.sleep(0.05)
    return None


def _busy(folder: Path, holder: LockHolder | None) -> SatsightError:
    who = holder.describe() if holder is not None else "holder unknown"
    return SatsightError(
        f"{folder} is being written by another satsight process ({who}); wait for it to "
        "end or stop it, then run again (one writer per dataset folder)"
    )


def refuse_if_locked(folder: Path) -> None:
    """Raise when another process holds ``folder``'s lock (a check, not a lock: the lock
    itself is ``WriterLock``'s, which refuses a second holder in this process too)."""
    path = lock_path(folder)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            mine = holder is not None and (holder.pid, holder.host) == (
                os.getpid(), socket.gethostname())  # fmt: skip
            if not mine:
                raise _busy(folder, holder) from None
    finally:
        os.close(fd)


class WriterLock:
    """The lock of dataset folder ``folder`` for this process; a context manager.

    The folder is created if needed (and removed again on release if it was created here
    and is left empty). Release deletes the lock file while still holding it, so that a
    waiting process never locks a file that is no longer the folder's lock.
    """

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.path = lock_path(self.folder)
        self._fd: int | None = None
        self._created = False

    def acquire(self) -> WriterLock:
        if self.folder.exists() and not self.folder.is_dir():
            raise SatsightError(f"output path {self.folder} exists and is not a folder")
        if not self.folder.exists():
            try:
                self.folder.mkdir(parents=True)
                self._created = True
            except FileExistsError:
                pass
            except OSError as error:
                raise SatsightError(
                    f"cannot create the folder {self.folder}: {error.strerror or error}"
                ) from None
        while self._fd is None:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as error:
                raise SatsightError(
                    f"cannot write the lock file {self.path}: {error.strerror or error}; "
                    "choose a folder you can write in"
                ) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(fd)
                os.close(fd)
                raise _busy(self.folder, holder) from None
            # The holder that just ended may have deleted the file we opened: lock the
            # file that is at the path now.
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            self._fd = fd
        try:
            self._take_over(_read(self._fd))
        except BaseException:  # the file is another writer's: leave it as it is
            os.close(self._fd)
            self._fd = None
            raise
        try:
            os.ftruncate(self._fd, 0)
            os.lseek(self._fd, 0, os.SEEK_SET)
            os.write(self._fd, LockHolder.me().text())
            os.fsync(self._fd)
        except BaseException:
            self.release()
            raise
        return self

    def _take_over(self, previous: LockHolder | None) -> None:
        """Note (or refuse) a lock file that a writer left behind without its lock."""
        if previous is None:
            return
        if previous.host != socket.gethostname():
            raise SatsightError(
                f"{self.path} names a writer on {previous.host} ({previous.describe()}); "
                "if that run has ended, delete the lock file and run again"
            )
        if previous.alive_here() and previous.pid != os.getpid():
            why = "its process id is now another process's"
        else:
            why = "its process is gone"
        log.warning(
            "%s: taking over the lock of an earlier writer that ended without releasing "
            "it (%s; %s)", self.folder, previous.describe(), why,
        )  # fmt: skip

    def release(self) -> None:
        if self._fd is None:
            return
        with suppress(OSError):
            self.path.unlink(missing_ok=True)
        os.close(self._fd)
        self._fd = None
        if self._created:
            with suppress(OSError):
                self.folder.rmdir()  # only if empty

    def __enter__(self) -> WriterLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
