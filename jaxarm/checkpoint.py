"""Orbax checkpoints of any pytree state plus a JSON description, keyed by an integer step.

Orbax writes each step to a temporary folder and renames it when complete, so a run killed while saving resumes
from the previous complete checkpoint. Restoring needs the state's structure (a state or ``jax.eval_shape`` of its
constructor); arrays come back with their exact bits, so a resumed run equals an uninterrupted one.
"""
from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp


class Checkpointer:
    """Save and restore ``(state, meta)`` in ``directory``, keeping the last ``max_to_keep`` steps."""

    def __init__(self, directory: str | Path, max_to_keep: int = 2):
        self.directory = Path(directory).absolute()
        options = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True,
                                               enable_async_checkpointing=False)
        self._manager = ocp.CheckpointManager(self.directory, options=options, item_names=("state", "meta"))

    def latest_step(self) -> int | None:
        return self._manager.latest_step()

    def save(self, step: int, state, meta: dict) -> None:
        """Save (blocking: the checkpoint is complete on return)."""
        self._manager.save(int(step), args=ocp.args.Composite(state=ocp.args.StandardSave(state),
                                                              meta=ocp.args.JsonSave(meta)), force=True)
        self._manager.wait_until_finished()

    def restore(self, like_state, step: int | None = None):
        """``(state, meta)`` at ``step`` (default: the latest); ``like_state`` gives structure, shapes and dtypes."""
        step = self.latest_step() if step is None else step
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {self.directory}")
        abstract = jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), like_state)
        restored = self._manager.restore(step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract),
                                                                       meta=ocp.args.JsonRestore()))
        # Orbax returns device-committed arrays; uncommitted copies hit the already-compiled functions' cache.
        return jax.tree.map(lambda x: jnp.asarray(np.asarray(x)), restored.state), restored.meta

    def read_meta(self, step: int | None = None) -> dict:
        step = self.latest_step() if step is None else step
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {self.directory}")
        return self._manager.restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore())).meta

    def close(self) -> None:
        self._manager.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
