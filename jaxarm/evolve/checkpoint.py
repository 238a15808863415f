"""Orbax checkpoints of a search between chunks: the whole :class:`SearchState` plus a JSON description.

A checkpoint is the :class:`~jaxarm.evolve.search.SearchState` pytree (strategy state, raw ``uint32`` PRNG key,
history, top-k archive) and a JSON ``meta`` item (the configuration the search was started with), under
``DIR/<generation>``, written by the project's :class:`jaxarm.checkpoint.Checkpointer` (atomic steps, exact bits on
restore, so the resumed search equals the uninterrupted one).
"""
from __future__ import annotations

from jaxarm.checkpoint import Checkpointer


class SearchCheckpointer(Checkpointer):
    """A :class:`Checkpointer` keyed by the search state's generation."""

    def latest_generation(self) -> int | None:
        """Generation of the newest complete checkpoint, or None."""
        return self.latest_step()

    def save(self, state, meta: dict) -> None:  # type: ignore[override]
        """Save ``state`` at its generation (blocking: the checkpoint is complete on return)."""
        super().save(int(state.generation), state, meta)

    def restore(self, like_state, generation: int | None = None):  # type: ignore[override]
        """``(state, meta)`` of the checkpoint at ``generation`` (default: the latest)."""
        return super().restore(like_state, generation)
