"""Orbax checkpoints of any pytree state plus a JSON description, keyed by an integer step.

Orbax writes each step to a temporary folder and renames it when complete, so a run killed while saving resumes
from the previous complete checkpoint. A step that was completed but later damaged (a truncated or missing data
file, as a full disk leaves it) is found when it is read: it is moved aside to ``DIR/unreadable-<step>`` with a
one-line warning naming it, and the previous step is used, so nothing older is lost and the run resumes.
Restoring needs the state's structure (a state or ``jax.eval_shape`` of its constructor); arrays come back with
their exact bits, so a resumed run equals an uninterrupted one.
"""
from __future__ import annotations

import hashlib
import json
import contextlib
import io
import logging
import os
import re
import shutil
import sys
import time
from pathlib import Path
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp
from jax.sharding import NamedSharding

from jaxarm.runfolder import FolderError


#: Name of the integrity manifest in every step folder.
MANIFEST = "MANIFEST"


def _warn(message: str) -> None:
    print(f"jaxarm: warning: {message}", file=sys.stderr, flush=True)


def _file_table(folder: Path) -> dict[str, list]:
    """{relative path: [size in bytes, sha256]} of every file below ``folder`` but the manifest."""
    table = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and path.name != MANIFEST:
            table[str(path.relative_to(folder))] = [path.stat().st_size, hashlib.sha256(path.read_bytes()).hexdigest()]
    return table


def write_manifest(folder: Path) -> None:
    """Write ``folder/MANIFEST`` atomically (a step killed before it has none and is checked by orbax's read)."""
    tmp = folder / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(_file_table(folder)))
    os.replace(tmp, folder / MANIFEST)


def check_manifest(folder: Path) -> None:
    """Raise ValueError naming the first file of ``folder`` that is missing, added, resized or changed."""
    path = folder / MANIFEST
    if not path.exists():
        return
    expected, found = json.loads(path.read_text()), _file_table(folder)
    for name in sorted(set(expected) | set(found)):
        if name not in found:
            raise ValueError(f"{name} is missing")
        if name not in expected:
            continue   # a file orbax adds on read is no damage
        if found[name][0] != expected[name][0]:
            raise ValueError(f"{name} has {found[name][0]} bytes, {expected[name][0]} written")
        if found[name][1] != expected[name][1]:
            raise ValueError(f"{name} changed since it was written")


#: NamedTuple fields renamed since checkpoints were first written, new name -> old name: a step written before reads
#: into the new structure (``jaxarm.train.Trained.babble`` became ``.rule`` with the learning-rule interface).
RENAMED_FIELDS = {"rule": "babble"}


def _renamed(x) -> bool:
    return isinstance(x, tuple) and any(f in RENAMED_FIELDS for f in getattr(x, "_fields", ()))


def _old_names(tree):
    """``tree`` with every NamedTuple that has a renamed field as a dict under the old names (orbax matches a
    NamedTuple's checkpoint by field names, so a dict of them reads it)."""
    return jax.tree.map(lambda x: {RENAMED_FIELDS.get(f, f): _old_names(v) for f, v in zip(x._fields, x)}
                        if _renamed(x) else x, tree, is_leaf=_renamed)


def _new_names(restored, like):
    """The inverse of :func:`_old_names`: ``restored`` (read through it) in ``like``'s structure."""
    return jax.tree.map(lambda x, r: type(x)(*(_new_names(r[RENAMED_FIELDS.get(f, f)], v)
                                               for f, v in zip(x._fields, x))) if _renamed(x) else r,
                        like, restored, is_leaf=_renamed)


class _UnreadFutureErrors(logging.Filter):
    """Drops asyncio's "... exception was never retrieved" records (a failed checkpoint's sibling writes)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "exception was never retrieved" not in str(record.msg)


def _drop_unread_future_errors() -> None:
    log = logging.getLogger("asyncio")
    if not any(isinstance(f, _UnreadFutureErrors) for f in log.filters):
        log.addFilter(_UnreadFutureErrors())


class CheckpointWriteError(FolderError):
    """A checkpoint could not be written (:meth:`Checkpointer.save`); its message is one line (the commands print
    it as ``jaxarm COMMAND: ...`` and exit with status 2)."""


def write_error_reason(error: BaseException) -> str:
    """The reason of a failed write in a few words: the OS error (orbax's TensorStore reports it inside a longer
    message as ``[os_error_code='28']``), else the error's first line."""
    if isinstance(error, OSError) and error.strerror:
        return error.strerror
    text = str(error)
    code = re.search(r"os_error_code='(\d+)'", text)
    if code:
        return os.strerror(int(code.group(1)))
    first = text.strip().splitlines()[0] if text.strip() else type(error).__name__
    return first[:160]


class _Held:
    """What :func:`_held_output` kept back: absl log records and text written to stderr."""

    def __init__(self):
        self.records: list[logging.LogRecord] = []
        self.stderr = io.StringIO()

    def filter(self, record: logging.LogRecord) -> bool:
        self.records.append(record)
        return False

    def replay(self) -> None:
        for record in self.records:
            logging.getLogger(record.name).handle(record)
        if self.stderr.getvalue():
            sys.stderr.write(self.stderr.getvalue())


@contextlib.contextmanager
def _held_output():
    """Hold back absl's log records and stderr (orbax's threads report a failed write there, in hundreds of lines)
    while a checkpoint is written; :meth:`_Held.replay` lets them out when the write succeeded."""
    held, absl_logger = _Held(), logging.getLogger("absl")
    absl_logger.addFilter(held)
    try:
        with contextlib.redirect_stderr(held.stderr):
            yield held
    finally:
        absl_logger.removeFilter(held)


class Checkpointer:
    """Save and restore ``(state, meta)`` in ``directory``, keeping the last ``max_to_keep`` steps."""

    def __init__(self, directory: str | Path, max_to_keep: int = 2, warn: Callable[[str], None] = _warn):
        self.directory = Path(directory).absolute()
        self._warn = warn
        self.max_to_keep = max_to_keep
        options = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True,
                                               enable_async_checkpointing=False)
        self._manager = ocp.CheckpointManager(self.directory, options=options, item_names=("state", "meta"))

    def latest_step(self) -> int | None:
        return self._manager.latest_step()

    def all_steps(self) -> list[int]:
        """The complete steps in the folder, oldest first."""
        return sorted(self._manager.all_steps())

    def step_bytes(self) -> int | None:
        """Bytes on disk of the newest step (what the next one will take, about), or None without one."""
        step = self.latest_step()
        if step is None:
            return None
        return sum(f.stat().st_size for f in (self.directory / str(step)).rglob("*") if f.is_file())

    def save(self, step: int, state, meta: dict) -> None:
        """Save (blocking: the checkpoint is complete on return). With several processes every one calls this with
        its shards of the global arrays (orbax writes each process's part); process 0 writes the manifest.

        A write that fails (a full disk, a file system gone read-only) raises :class:`CheckpointWriteError`, one
        line naming the step, the folder and the reason, after removing what was written of this step; orbax's own
        log of the failure is dropped, and the steps written before are untouched."""
        from jaxarm import parallel

        failure = None
        with _held_output() as held:
            try:
                self._manager.save(int(step), args=ocp.args.Composite(state=ocp.args.StandardSave(state),
                                                                      meta=ocp.args.JsonSave(meta)), force=True)
                self._manager.wait_until_finished()
            except Exception as e:  # noqa: BLE001 - any failure of the write is reported as one line
                failure = e
                self._discard(int(step))     # held too: TensorStore's writes still failing print as they end
        if failure is not None:
            # orbax's sibling writes of this step failed too; asyncio logs each unread one, with its traceback, when
            # its future is collected (after this line, as the command exits): the same failure, already reported
            _drop_unread_future_errors()
            raise CheckpointWriteError(self._write_failure(int(step), failure)) from failure
        held.replay()
        parallel.barrier(f"checkpoint-saved-{step}")
        if parallel.is_main_process():
            try:
                write_manifest(self.directory / str(int(step)))
            except OSError as e:
                (self.directory / str(int(step)) / (MANIFEST + ".tmp")).unlink(missing_ok=True)
                raise CheckpointWriteError(self._write_failure(int(step), e)) from e
        parallel.barrier(f"checkpoint-manifest-{step}")

    def _discard(self, step: int) -> None:
        """Remove the unfinished folders of ``step`` (orbax's temporary ones); complete steps are never touched.
        Orbax's threads may still be writing when its save has already failed, so the folders are removed until
        none has come back for a moment (at most a few seconds)."""
        with contextlib.suppress(Exception):
            self._manager.wait_until_finished()
        quiet_since, deadline = time.monotonic(), time.monotonic() + 5.0
        while time.monotonic() < deadline and time.monotonic() - quiet_since < 0.5:
            partial = list(self.directory.glob(f"{step}.orbax-checkpoint-tmp*"))
            for folder in partial:
                shutil.rmtree(folder, ignore_errors=True)
            if partial:
                quiet_since = time.monotonic()
            time.sleep(0.05)
        with contextlib.suppress(Exception):   # the manager is not used again after a failed write
            self._manager.reload()

    def _write_failure(self, step: int, error: Exception) -> str:
        kept = [s for s in self._manager.all_steps() if s != step] if self.directory.is_dir() else []
        then = (f"the last good checkpoint (step {max(kept)}) is intact: free space and run the same command again "
                "to resume from it" if kept else "no earlier checkpoint: the run starts afresh when run again")
        return f"cannot write checkpoint step {step} in {self.directory}: {write_error_reason(error)}; {then}"

    def _newest_readable(self, read, step: int | None):
        """``read(step)`` at ``step``, or (step None) at the newest step that can be read, moving unreadable newer
        steps aside. Returns (step, value)."""
        if step is not None:
            return step, read(step)
        while (step := self.latest_step()) is not None:
            try:
                check_manifest(self.directory / str(step))
                return step, read(step)
            except Exception as e:  # noqa: BLE001 - any failure to read a step means that step is damaged
                self._quarantine(step, e)
        raise FileNotFoundError(f"no checkpoint in {self.directory}")

    def _quarantine(self, step: int, error: Exception) -> None:
        from jaxarm import parallel

        bad = self.directory / str(step)
        aside = self.directory / f"unreadable-{step}-{time.strftime('%Y%m%dT%H%M%S')}"
        parallel.barrier(f"checkpoint-check-{step}")     # every process has judged the step before it moves
        if parallel.is_main_process():
            bad.rename(aside)
        parallel.barrier(f"checkpoint-moved-{step}")
        self._manager.reload()
        why = str(error).strip().splitlines()[0][:160] if str(error).strip() else type(error).__name__
        previous = self.latest_step()
        then = f"using step {previous}" if previous is not None else "no earlier checkpoint: starting afresh"
        self._warn(f"checkpoint {bad} is unreadable ({why}); moved to {aside.name}, {then}")

    def restore(self, like_state, step: int | None = None):
        """``(state, meta)`` at ``step`` (default: the newest readable step; see the module docstring);
        ``like_state`` gives structure, shapes, dtypes and, where its leaves have one, the sharding to restore into
        (global arrays split over the device mesh, each process reading its part). :meth:`latest_step` is the step
        restored."""
        def mesh_sharding(x):
            sharding = getattr(x, "sharding", None)
            return sharding if isinstance(sharding, NamedSharding) else None

        abstract = jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=mesh_sharding(x)),
                                like_state)

        def placed(x, like):
            # Orbax returns device-committed arrays; for a state not on the mesh, uncommitted copies hit the
            # functions already compiled for the state it replaces.
            return x if like.sharding is not None else jnp.asarray(np.asarray(x))

        def read_into(s, target):
            return self._manager.restore(s, args=ocp.args.Composite(state=ocp.args.StandardRestore(target),
                                                                    meta=ocp.args.JsonRestore()))

        def read(s):
            try:
                restored = read_into(s, abstract)
                state = restored.state
            except Exception as error:  # noqa: BLE001 - a step written before a field was renamed, or damaged
                if not any(map(_renamed, jax.tree.leaves(abstract, is_leaf=_renamed))):
                    raise
                try:
                    restored = read_into(s, _old_names(abstract))
                except Exception:  # noqa: BLE001 - not the old structure either: report the first failure
                    raise error from None
                state = _new_names(restored.state, abstract)
            return jax.tree.map(placed, state, abstract), restored.meta

        return self._newest_readable(read, step)[1]

    def read_meta(self, step: int | None = None) -> dict | None:
        """The JSON description at ``step``, or (step None) at the newest step that can be read, or None if there is
        no readable checkpoint (then there is nothing to resume)."""
        try:
            return self._newest_readable(
                lambda s: self._manager.restore(s, args=ocp.args.Composite(meta=ocp.args.JsonRestore())).meta,
                step)[1]
        except FileNotFoundError:
            if step is not None:
                raise
            return None

    def close(self) -> None:
        self._manager.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
