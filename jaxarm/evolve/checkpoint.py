"""Orbax checkpoints of a search between chunks: the whole :class:`SearchState` plus a JSON description.

A checkpoint is the :class:`~jaxarm.evolve.search.SearchState` pytree (strategy state, raw ``uint32`` PRNG key,
history, top-k archive; saved with ``ocp.args.StandardSave``) and a JSON ``meta`` item (the configuration the search
was started with), under ``DIR/<generation>``. Orbax writes each step to a temporary folder and renames it when
complete, so a search killed while saving resumes from the previous complete checkpoint. Restoring needs the
state's structure, which :meth:`SearchCheckpointer.restore` takes from the search's own ``init`` (abstractly, without
running it); the arrays come back with their exact bits, so the resumed search equals the uninterrupted one.
"""
from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp


class SearchCheckpointer:
    """Save and restore search states in ``directory`` (kept: the last ``max_to_keep`` checkpoints)."""

    def __init__(self, directory: str | Path, max_to_keep: int = 2):
        self.directory = Path(directory).absolute()
        options = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True,
                                               enable_async_checkpointing=False)
        self._manager = ocp.CheckpointManager(self.directory, options=options, item_names=("state", "meta"))

    def latest_generation(self) -> int | None:
        """Generation of the newest complete checkpoint, or None."""
        return self._manager.latest_step()

    def save(self, state, meta: dict) -> None:
        """Save ``state`` at its generation (blocking: the checkpoint is complete on return)."""
        step = int(state.generation)
        self._manager.save(step, args=ocp.args.Composite(state=ocp.args.StandardSave(state),
                                                         meta=ocp.args.JsonSave(meta)), force=True)
        self._manager.wait_until_finished()

    def restore(self, like_state, generation: int | None = None):
        """``(state, meta)`` of the checkpoint at ``generation`` (default: the latest). ``like_state``: a state or an
        abstract one (``jax.eval_shape(search.init, key)``) giving the structure, shapes and dtypes."""
        step = self.latest_generation() if generation is None else generation
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {self.directory}")
        abstract = jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), like_state)
        restored = self._manager.restore(step, args=ocp.args.Composite(state=ocp.args.StandardRestore(abstract),
                                                                       meta=ocp.args.JsonRestore()))
        # Orbax returns arrays committed to a device; a fresh state's are not, and jit keys its cache on that: the
        # same arrays, uncommitted, run the already compiled chunk.
        state = jax.tree.map(lambda x: jnp.asarray(np.asarray(x)), restored.state)
        return state, restored.meta

    def read_meta(self, generation: int | None = None) -> dict:
        """The JSON description saved with the checkpoint at ``generation`` (default: the latest)."""
        step = self.latest_generation() if generation is None else generation
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {self.directory}")
        return self._manager.restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore())).meta

    def close(self) -> None:
        self._manager.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
