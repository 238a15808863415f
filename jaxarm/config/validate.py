"""Validation helpers shared by every static configuration.

Configurations are frozen dataclasses checked once in ``__post_init__``. A wrong value raises one
:class:`ConfigError` that names the field, the value and the allowed range, before anything reaches JAX.
"""
from __future__ import annotations

import math
from typing import Any, Iterable


class ConfigError(ValueError):
    """A configuration value is outside its allowed range or of the wrong kind."""


def _name(owner: Any, field: str) -> str:
    return f"{type(owner).__name__}.{field}"


def check_range(owner: Any, field: str, lo: float | None = None, hi: float | None = None,
                *, lo_open: bool = False, hi_open: bool = False, integer: bool = False) -> None:
    """Raise :class:`ConfigError` unless ``owner.field`` is a finite number within [lo, hi].

    ``lo_open``/``hi_open`` make the bound exclusive; ``integer`` requires an ``int`` (bools are rejected).
    """
    value = getattr(owner, field)
    kind = "an integer" if integer else "a number"
    ok_type = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type:
        raise ConfigError(f"{_name(owner, field)} = {value!r}: must be {kind}{_range_text(lo, hi, lo_open, hi_open)}")
    if not math.isfinite(value):
        raise ConfigError(f"{_name(owner, field)} = {value!r}: must be finite{_range_text(lo, hi, lo_open, hi_open)}")
    too_low = lo is not None and (value <= lo if lo_open else value < lo)
    too_high = hi is not None and (value >= hi if hi_open else value > hi)
    if too_low or too_high:
        raise ConfigError(f"{_name(owner, field)} = {value!r} is out of range; allowed{_range_text(lo, hi, lo_open, hi_open)}")


def check_choice(owner: Any, field: str, choices: Iterable[Any]) -> None:
    """Raise :class:`ConfigError` unless ``owner.field`` is one of ``choices``."""
    value = getattr(owner, field)
    choices = tuple(choices)
    if value not in choices:
        raise ConfigError(f"{_name(owner, field)} = {value!r}: must be one of {', '.join(map(repr, choices))}")


def check_interval(owner: Any, field: str, lo: float | None = None, hi: float | None = None) -> None:
    """Raise unless ``owner.field`` is a pair (a, b) with a < b, both within [lo, hi]."""
    value = getattr(owner, field)
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{_name(owner, field)} = {value!r}: must be a pair (low, high)") from None
    bounds = _range_text(lo, hi, False, False)
    if not (math.isfinite(a) and math.isfinite(b)) or a >= b:
        raise ConfigError(f"{_name(owner, field)} = {value!r}: need finite low < high{bounds}")
    if (lo is not None and a < lo) or (hi is not None and b > hi):
        raise ConfigError(f"{_name(owner, field)} = {value!r} is out of range; both ends{bounds}")


def _range_text(lo, hi, lo_open, hi_open) -> str:
    if lo is None and hi is None:
        return ""
    if hi is None:
        return f" {'>' if lo_open else '>='} {lo}"
    if lo is None:
        return f" {'<' if hi_open else '<='} {hi}"
    return f" in {'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
