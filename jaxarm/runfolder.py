"""The output folder of a batch command (``jaxarm train``, ``reproduce``, ``evolve``, ``rerank``): checked before
any work starts, and held by one command at a time.

* :func:`folder_argument`: the argparse type of ``--out`` (an empty value is refused, not taken as the current folder).
* :func:`prepare`: ``--out`` naming an existing file, a folder that cannot be created or written (a read-only file
  system, no permission) or a full disk is refused with one line, before JAX computes anything.
* :func:`check_space`: before training, the free space against the checkpoints the run will write.
* :class:`FolderLock`: ``OUT/jaxarm.lock``, an exclusive ``flock`` held while the command runs and holding the
  holder's PID, host and command: a second command on the same folder is refused naming them. The kernel drops the
  lock when its process dies (a ``kill -9`` included), so the lock file a killed run leaves behind is stale: the next
  command takes it over with a one-line note naming the dead holder.

Every refusal is a :class:`FolderError` (a :class:`~jaxarm.config.validate.ConfigError`): the commands print it as
one line, ``jaxarm COMMAND: ...``, and exit with status 2.
"""
from __future__ import annotations

import argparse
import errno
import json
import os
import shutil
import socket
import sys
import tempfile
import time
from pathlib import Path

from jaxarm.config.validate import ConfigError

#: The lock file in a run folder.
LOCK_FILE = "jaxarm.lock"
#: Below this much free space on ``--out``'s file system a run is refused at once (the disk is full).
MIN_FREE_BYTES = 1 << 20


class FolderError(ConfigError):
    """An output folder that cannot be used (in use, a file, not writable, full) or a write that failed in it."""


def folder_argument(text: str) -> Path:
    """argparse type of a folder option: a non-empty path."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must name a folder, not be empty (use . for the current folder)")
    return Path(text)


folder_argument.__name__ = "folder"


def _reason(err: OSError) -> str:
    return err.strerror or str(err)


def free_bytes(path: Path) -> int:
    """Free bytes on the file system holding ``path`` (its nearest existing parent)."""
    path = Path(path).absolute()
    while not path.exists():
        path = path.parent
    return shutil.disk_usage(path).free


def _mb(n: float) -> str:
    return f"{n / 2**20:.1f} MB"


def prepare(path: Path, option: str = "--out") -> Path:
    """Create the folder ``path`` (with its parents) and check that a file can be written in it; a
    :class:`FolderError` naming ``option`` otherwise: ``path`` is a file, cannot be created or written (read-only
    file system, permissions), or its file system has less than :data:`MIN_FREE_BYTES` free."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FolderError(f"{option} {path}: is a file, not a folder; give a folder (it is created if missing)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        file = next(p for p in [path, *path.parents] if p.exists() and not p.is_dir())
        raise FolderError(f"{option} {path}: cannot create it: {file} is a file") from None
    except OSError as e:
        raise FolderError(f"{option} {path}: cannot create it: {_reason(e)}") from None
    try:
        with tempfile.TemporaryFile(dir=path) as f:
            f.write(b"x")
            f.flush()
            os.fsync(f.fileno())
    except OSError as e:
        raise FolderError(f"{option} {path}: cannot write there: {_reason(e)}") from None
    free = free_bytes(path)
    if free < MIN_FREE_BYTES:
        raise FolderError(f"{option} {path}: its file system is full ({_mb(free)} free); free space or give "
                          f"another {option}")
    return path


def check_space(path: Path, step_bytes: int, option: str = "--out") -> None:
    """Refuse (:class:`FolderError`) when ``path``'s file system has less free space than the next checkpoint needs,
    ``step_bytes``: the newest step's size on disk, or before the first the state's size in memory (an upper bound:
    orbax compresses)."""
    free = free_bytes(path)
    if free < step_bytes:
        raise FolderError(f"{option} {path}: {_mb(free)} free on its file system, and the next checkpoint needs "
                          f"about {_mb(step_bytes)}; free space or give another {option}")


def _start_ticks(pid: int) -> int | None:
    """The process's start time in clock ticks since boot (Linux), which tells a reused PID from its holder."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return int(stat.rsplit(")", 1)[1].split()[19])
    except (OSError, IndexError, ValueError):
        return None


def pid_alive(pid: int, start_ticks: int | None = None) -> bool:
    """Whether process ``pid`` runs on this host (and, where ``start_ticks`` is known, is the same process)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass      # exists, another user's
    if start_ticks is not None:
        now = _start_ticks(pid)
        return now is None or now == start_ticks
    return True


def _describe(holder: dict) -> str:
    return (f"{holder.get('command', 'a jaxarm command')} (PID {holder.get('pid', '?')} on host "
            f"{holder.get('host', '?')}, since {holder.get('started', '?')})")


class FolderLock:
    """``folder/jaxarm.lock`` held by this process (a context manager; see the module docstring). ``command``: what
    the lock file says holds it. ``warn``: where the note about a stale lock goes."""

    def __init__(self, folder: Path, command: str, option: str = "--out", warn=None):
        self.folder, self.command, self.option = Path(folder), command, option
        self.path = self.folder / LOCK_FILE
        self._fd: int | None = None
        self._warn = warn or (lambda m: print(f"jaxarm: note: {m}", file=sys.stderr, flush=True))

    def _read(self, fd: int | None = None) -> dict:
        try:
            if fd is not None:
                os.lseek(fd, 0, os.SEEK_SET)
                text = os.read(fd, 1 << 16).decode("utf-8", "replace")
            else:
                text = self.path.read_text(errors="replace")
            holder = json.loads(text) if text.strip() else {}
            return holder if isinstance(holder, dict) else {"damaged": text[:60]}
        except json.JSONDecodeError:
            return {"damaged": text[:60]}
        except OSError:
            return {}

    def _mine(self) -> dict:
        return {"pid": os.getpid(), "host": socket.gethostname(), "command": self.command,
                "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "start_ticks": _start_ticks(os.getpid())}

    def _in_use(self, holder: dict) -> FolderError:
        return FolderError(f"{self.option} {self.folder}: in use by {_describe(holder)}; wait for it to end or give "
                           f"another {self.option} ({self.path} holds its lock)")

    def acquire(self) -> "FolderLock":
        import fcntl

        for _ in range(10):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise FolderError(f"{self.option} {self.folder}: cannot create its lock file {self.path.name}: "
                                  f"{_reason(e)}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = self._read(fd)
                os.close(fd)
                raise self._in_use(holder) from None
            except OSError as e:       # a file system without flock (some network mounts): the PID decides
                if e.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
                    os.close(fd)
                    raise
                holder = self._read(fd)
                if holder.get("pid") and (holder.get("host") != socket.gethostname()
                                          or pid_alive(int(holder["pid"]), holder.get("start_ticks"))):
                    os.close(fd)
                    raise self._in_use(holder) from None
            try:            # the file may have been removed by its holder between our open and our lock
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            previous = self._read(fd)
            if previous:
                self._warn(f"{self.path}: taking over the lock of {_describe(previous)}, which is no longer "
                           "running (killed?); its last checkpoint is resumed")
            os.ftruncate(fd, 0)
            os.lseek(fd, 0, os.SEEK_SET)
            os.write(fd, json.dumps(self._mine()).encode())
            os.fsync(fd)
            self._fd = fd
            return self
        raise FolderError(f"{self.option} {self.folder}: its lock file {self.path.name} keeps changing; is another "
                          "command starting there?")

    def release(self) -> None:
        if self._fd is None:
            return
        try:
            if os.stat(self.path).st_ino == os.fstat(self._fd).st_ino:
                os.unlink(self.path)
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


# -- reading a run folder's files ---------------------------------------------------------------------------------

class DamagedFile(ValueError):
    """A run folder's file that cannot be read or lacks what its reader needs; the message names the file and what
    is wrong, in one line."""


def read_json(path: Path) -> dict:
    """A JSON object from ``path``; :class:`DamagedFile` when it is unreadable, not JSON or not an object."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise DamagedFile(f"{path}: not valid JSON ({e.msg}, line {e.lineno} column {e.colno}); the file is "
                          "damaged: rerun the command that wrote it") from None
    except UnicodeDecodeError:
        raise DamagedFile(f"{path}: not text (binary data); the file is damaged: rerun the command that wrote "
                          "it") from None
    except OSError as e:
        raise DamagedFile(f"{path}: cannot be read ({_reason(e)})") from None
    if not isinstance(data, dict):
        raise DamagedFile(f"{path}: holds a JSON {type(data).__name__}, not the object written by jaxarm")
    return data


def read_npz(path: Path, required: tuple[str, ...] = ()) -> dict:
    """Every array of the ``.npz`` at ``path`` (read whole); :class:`DamagedFile` when it is not a readable ``.npz``
    (random bytes, truncated) or lacks one of ``required``."""
    import numpy as np

    path = Path(path)
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as e:
        raise DamagedFile(f"{path}: cannot be read ({_reason(e)})") from None
    if head not in (b"PK\x03\x04", b"PK\x05\x06"):
        raise DamagedFile(f"{path}: not an .npz archive ({'empty' if not head else 'overwritten or random bytes'}); "
                          "rerun the command that wrote it")
    try:
        with np.load(path, allow_pickle=False) as z:
            if not hasattr(z, "files"):
                raise ValueError("a single array, not an archive")
            data = {k: z[k] for k in z.files}
    except OSError as e:
        raise DamagedFile(f"{path}: cannot be read ({_reason(e)})") from None
    except Exception as e:  # noqa: BLE001 - zipfile, zlib, pickle and numpy errors alike: the file is damaged
        why = str(e).strip().splitlines()[0][:120] if str(e).strip() else type(e).__name__
        raise DamagedFile(f"{path}: a damaged .npz archive ({why}; truncated?); rerun the command that wrote "
                          "it") from None
    missing = [k for k in required if k not in data]
    if missing:
        raise DamagedFile(f"{path}: lacks {', '.join(missing)} (it holds {', '.join(sorted(data)) or 'nothing'}); "
                          "rerun the command that wrote it")
    return data


def lookup(data: dict, path: Path, *keys: str):
    """``data[keys[0]][keys[1]]...``; :class:`DamagedFile` naming ``path`` and the first missing key."""
    value = data
    for i, key in enumerate(keys):
        if not isinstance(value, dict) or key not in value:
            raise DamagedFile(f"{path}: lacks {'.'.join(keys[: i + 1])}; give a folder written by `jaxarm train` "
                              "or `jaxarm test` (or rerun it)")
        value = value[key]
    return value


class _Claim:
    """:func:`prepare` and, on process 0, the :class:`FolderLock`; a refusal on any process refuses on all of them
    (:func:`jaxarm.parallel.agree`), so no process is left waiting for one that has ended."""

    def __init__(self, folder: Path, command: str, option: str):
        self.folder, self.command, self.option, self.lock = folder, command, option, None

    def __enter__(self):
        from jaxarm import parallel

        refusal = None
        try:
            prepare(self.folder, self.option)
            if parallel.is_main_process():      # only process 0 of several locks: they share the folder
                self.lock = FolderLock(self.folder, self.command, self.option).acquire()
        except FolderError as e:
            refusal = str(e)
        refusal = parallel.agree(refusal)
        if refusal is not None:
            self.__exit__()
            raise FolderError(refusal)
        return self.lock

    def __exit__(self, *exc):
        if self.lock is not None:
            self.lock.release()
            self.lock = None


def claim(folder: Path, command: str, option: str = "--out") -> _Claim:
    """A context manager that :func:`prepare`-s the folder and holds its :class:`FolderLock` (see :class:`_Claim`)."""
    return _Claim(folder, command, option)


__all__ = ["DamagedFile", "FolderError", "FolderLock", "LOCK_FILE", "check_space", "claim", "folder_argument",
           "free_bytes", "lookup", "pid_alive", "prepare", "read_json", "read_npz"]
