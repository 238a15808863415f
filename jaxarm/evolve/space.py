"""The search space: which metaparameters evolution changes, their ranges, and the unit cube they are searched in.

Evolution searches a flat vector ``u`` in the unit cube [0, 1]^n, one entry per *free* metaparameter (in the order of
:data:`jaxarm.learning.metaparams.NAMES`). Entry ``u_i`` maps to the field's range [lo, hi] on its scale: linearly, or
geometrically for a "log" field (``lo * (hi/lo)**u_i``). The ranges and scales are the one table
:data:`jaxarm.learning.metaparams.BOUNDS`; a space may narrow or replace a field's range. Every other field is
*frozen* at a value (by default the published one, :meth:`MetaParams.original`).

The mapping clips ``u`` to [0, 1] first, so whatever a strategy proposes, the metaparameters evaluated are inside
the bounds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping

import jax.numpy as jnp
import numpy as np

from jaxarm.config.validate import ConfigError
from jaxarm.learning.metaparams import BOUNDS, NAMES, ORIGINAL, Bound, MetaParams

SCALES = ("log", "linear")


def _as_pairs(value, what: str) -> tuple:
    """Normalise a mapping / iterable of pairs into a tuple of pairs in :data:`NAMES` order."""
    items = dict(value.items() if isinstance(value, Mapping) else value)
    unknown = [k for k in items if k not in NAMES]
    if unknown:
        raise ConfigError(f"SearchSpace.{what}: unknown metaparameter {unknown[0]!r}; known: {', '.join(NAMES)}")
    return tuple((k, items[k]) for k in NAMES if k in items)


@dataclass(frozen=True)
class SearchSpace:
    """Which :class:`MetaParams` fields are searched, within which ranges, from which start point.

    Attributes (mappings may be given as dicts; they are stored as tuples of pairs so the space is hashable):
        frozen: ``{name: value}`` of fields held fixed, in the field's own units. A name given in ``freeze`` (see
            :meth:`make`) without a value is frozen at its published value.
        bounds: ``{name: (lo, hi, scale)}`` replacing :data:`BOUNDS` for searched fields (scale "log" or "linear").
        start: ``{name: value}`` of the start point (CMA-ES mean; the first member of a GA's first population) for
            searched fields; the others start at their published value.
        frozen_defaults: values of fields that are neither searched nor in ``frozen`` (there are none unless
            ``search`` was given to :meth:`make`); the published values.

    Raises :class:`ConfigError` naming the field for an unknown name, a non-finite value, a bad range or scale, a
    start outside its range, or a space with nothing left to search.
    """

    frozen: tuple = ()
    bounds: tuple = ()
    start: tuple = ()
    _bound_table: dict = field(default=None, init=False, repr=False, compare=False, hash=False)

    def __post_init__(self):
        frozen = _as_pairs(self.frozen, "frozen")
        for name, v in frozen:
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
                raise ConfigError(f"SearchSpace.frozen[{name!r}] = {v!r}: must be a finite number")
        frozen = tuple((k, float(v)) for k, v in frozen)
        bounds = _as_pairs(self.bounds, "bounds")
        table = dict(BOUNDS)
        norm_bounds = []
        for name, spec in bounds:
            try:
                lo, hi, scale = spec
                lo, hi = float(lo), float(hi)
            except (TypeError, ValueError):
                raise ConfigError(f"SearchSpace.bounds[{name!r}] = {spec!r}: must be (lo, hi, scale)") from None
            if scale not in SCALES:
                raise ConfigError(f"SearchSpace.bounds[{name!r}] scale = {scale!r}: must be one of "
                                  f"{', '.join(map(repr, SCALES))}")
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ConfigError(f"SearchSpace.bounds[{name!r}] = ({lo}, {hi}): need finite lo < hi")
            if scale == "log" and lo <= 0:
                raise ConfigError(f"SearchSpace.bounds[{name!r}] = ({lo}, {hi}, 'log'): a log scale needs lo > 0")
            table[name] = Bound(lo, hi, scale, BOUNDS[name].unit)
            norm_bounds.append((name, (lo, hi, scale)))
        frozen_names = {k for k, _ in frozen}
        start = _as_pairs(self.start, "start")
        for name, v in start:
            if name in frozen_names:
                raise ConfigError(f"SearchSpace.start[{name!r}]: the field is frozen; set its value in frozen")
            b = table[name]
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not (math.isfinite(v) and b.lo <= v <= b.hi):
                raise ConfigError(f"SearchSpace.start[{name!r}] = {v!r} is out of range; allowed in [{b.lo}, {b.hi}]")
        start = tuple((k, float(v)) for k, v in start)
        for name, _ in norm_bounds:
            if name in frozen_names:
                raise ConfigError(f"SearchSpace.bounds[{name!r}]: the field is frozen, a range has no effect")
        start_map = dict(start)
        for name in NAMES:   # the default start (the published value) must lie in a replaced range too
            b = table[name]
            if name not in frozen_names and name not in start_map and not (b.lo <= ORIGINAL[name] <= b.hi):
                raise ConfigError(f"SearchSpace.bounds[{name!r}] = ({b.lo}, {b.hi}) excludes the published value "
                                  f"{ORIGINAL[name]}; give a start value inside the range")
        if len(frozen_names) == len(NAMES):
            raise ConfigError("SearchSpace.frozen: every metaparameter is frozen; nothing left to search")
        object.__setattr__(self, "frozen", frozen)
        object.__setattr__(self, "bounds", tuple(norm_bounds))
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "_bound_table", table)

    # ----------------------------------------------------------------- construction
    @classmethod
    def make(cls, *, search: Iterable[str] | None = None, freeze: Iterable[str] | Mapping[str, float] = (),
             bounds: Mapping | None = None, start: Mapping | None = None) -> "SearchSpace":
        """Convenience constructor.

        ``search``: names to search (every other field frozen at its published value); ``None`` = all fields not in
        ``freeze``. ``freeze``: names (frozen at the published value) or ``{name: value}``.
        """
        if isinstance(freeze, Mapping):
            frozen = dict(freeze)
        else:
            frozen = {}
            for name in freeze:
                if name not in ORIGINAL:
                    raise ConfigError(f"SearchSpace.frozen: unknown metaparameter {name!r}; known: {', '.join(NAMES)}")
                frozen[name] = ORIGINAL[name]
        if search is not None:
            search = list(search)
            for name in search:
                if name not in ORIGINAL:
                    raise ConfigError(f"SearchSpace.search: unknown metaparameter {name!r}; known: {', '.join(NAMES)}")
                if name in frozen:
                    raise ConfigError(f"SearchSpace.search: {name!r} is both searched and frozen")
            for name in NAMES:
                if name not in search and name not in frozen:
                    frozen[name] = ORIGINAL[name]
        return cls(frozen=frozen, bounds=bounds or {}, start=start or {})

    # ----------------------------------------------------------------- queries
    @property
    def names(self) -> tuple[str, ...]:
        """Searched fields, in :data:`NAMES` order (the order of the unit vector)."""
        frozen = dict(self.frozen)
        return tuple(n for n in NAMES if n not in frozen)

    @property
    def n_dims(self) -> int:
        return len(self.names)

    def bound(self, name: str) -> Bound:
        """The range of field ``name`` in this space."""
        return self._bound_table[name]

    def start_values(self) -> dict[str, float]:
        """Start point of every field, in its own units (frozen fields at their frozen value)."""
        return {**ORIGINAL, **dict(self.start), **dict(self.frozen)}

    def start_unit(self) -> np.ndarray:
        """Start point of the searched fields in the unit cube, float32 (n_dims,)."""
        values = self.start_values()
        return np.asarray([self._value_to_unit(n, values[n]) for n in self.names], np.float32)

    def _value_to_unit(self, name: str, v: float) -> float:
        b = self.bound(name)
        if b.scale == "log":
            return (math.log(v) - math.log(b.lo)) / (math.log(b.hi) - math.log(b.lo))
        return (v - b.lo) / (b.hi - b.lo)

    def to_dict(self) -> dict:
        """JSON-ready description (for results and checkpoint metadata)."""
        return {
            "searched": {n: {"lo": self.bound(n).lo, "hi": self.bound(n).hi, "scale": self.bound(n).scale,
                             "unit": self.bound(n).unit, "start": self.start_values()[n]} for n in self.names},
            "frozen": dict(self.frozen),
        }

    # ----------------------------------------------------------------- traced mapping
    def to_metaparams(self, u) -> MetaParams:
        """Unit vector(s) ``u`` (..., n_dims) -> :class:`MetaParams` with the same leading axes. ``u`` is clipped to
        [0, 1] first, so every field is inside its range. Pure; works under ``jit``/``vmap``."""
        u = jnp.clip(jnp.asarray(u, jnp.float32), 0.0, 1.0)
        batch = u.shape[:-1]
        if u.shape[-1] != self.n_dims:
            raise ValueError(f"unit vector has {u.shape[-1]} entries; this space searches {self.n_dims}")
        frozen = dict(self.frozen)
        fields, i = {}, 0
        for name in NAMES:
            if name in frozen:
                fields[name] = jnp.full(batch, frozen[name], jnp.float32)
                continue
            b, x = self.bound(name), u[..., i]
            i += 1
            if b.scale == "log":
                v = jnp.exp(math.log(b.lo) + x * (math.log(b.hi) - math.log(b.lo)))
            else:
                v = b.lo + x * (b.hi - b.lo)
            fields[name] = jnp.clip(v, b.lo, b.hi)   # exp/log round-off must not leave the range
        return MetaParams(**fields)

    def to_unit(self, mp: MetaParams):
        """:class:`MetaParams` -> unit vector(s) (..., n_dims) of the searched fields (not clipped)."""
        cols = []
        for name in self.names:
            b, v = self.bound(name), jnp.asarray(getattr(mp, name), jnp.float32)
            if b.scale == "log":
                cols.append((jnp.log(v) - math.log(b.lo)) / (math.log(b.hi) - math.log(b.lo)))
            else:
                cols.append((v - b.lo) / (b.hi - b.lo))
        return jnp.stack(cols, axis=-1)
