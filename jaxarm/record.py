"""Spike recording in the closed loop: a static option, stored compactly, with a stated and checked memory bound.

What is recorded (``RecordConfig``, static: with no record the compiled loop is the one without this module):

* the spikes of every cell (global ids, :mod:`jaxarm.network.populations`) in chosen windows of a run: the 1 s
  test, and optionally the last ``train_last_s`` seconds of chosen training epochs;
* with them, per 10 ms interval of the window, the joint angles, hand, excitations and (musculoskeletal arm) each
  muscle's activation, forces and lengths.

How: :meth:`jaxarm.network.network.Network.run` with ``collect=True`` gives every clock step's spikes (both
kernels). Inside the loop's ``lax.scan`` each interval's (steps, cells) bool block is packed into 32-bit words
(bit b of word k: flat index 32 k + b, flat = step in the interval x n_all + cell id), and only the non-zero words
are appended to a fixed-capacity buffer, each as a slot of two uint32 (the word's code, interval x words per
interval + k, and its bits), by one scatter at a running counter. Packing first matters: a scatter of one update
per (step, cell) slot cost as much as the rest of the loop (training throughput halved); one per word is 32 times
fewer updates. Slots beyond the capacity are not written but still counted: ``used`` above the capacity is an
overflow, which :func:`check_overflow` turns into an error naming the capacity and the option that sets it (never a
silent truncation). :func:`decode` turns the slots back into (step, cell) pairs on the host; :mod:`jaxarm.recordfile`
writes them to ``spikes.npz`` and reads them back.

Memory bound: capacity = ceil(``max_rate_hz`` x n_all cells x window s) slots of :data:`BYTES_PER_SLOT` bytes per
network. A slot holds at least one spike, so a window whose mean rate stays under ``max_rate_hz`` always fits
(default 50 Hz, ten times the test rate of the networks trained here; 35,200 slots = 282 KB per network per
recorded second of the 704 cells). :func:`check_memory` refuses a batch whose buffers would exceed ``max_mb``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxarm.config.validate import ConfigError

#: Spikes per packed word.
WORD_BITS = 32
#: One buffer slot: a word's code and its bits, two uint32.
BYTES_PER_SLOT = 8
#: Word codes are uint32: a window may hold at most this many words.
MAX_CODES = 2 ** 32


@dataclass(frozen=True)
class RecordConfig:
    """What a run records (static).

    Attributes:
        max_rate_hz: bound on the mean firing rate over every cell (P included) of a recorded window, Hz; it sets
            each window's buffer capacity, ceil(max_rate_hz x n_all x window s) slots of up to 32 spikes. A
            network whose spikes need more slots fails with an error naming this bound (``--record-max-rate-hz``).
        max_mb: most memory the buffers of one batch may take, MB (``--record-max-mb``).
        train_last_s: also record the last this many seconds of the epochs in ``epochs`` (0: the tests only), s.
        epochs: 1-based epochs whose last ``train_last_s`` seconds are recorded; empty: the last epoch.
        networks: indices (0-based, in the run's order) of the networks whose records are written; empty: all.
            Every network of a batch is recorded on the device (one compiled program); this selects what is saved.
    """

    max_rate_hz: float = 50.0
    max_mb: float = 1024.0
    train_last_s: float = 0.0
    epochs: tuple[int, ...] = ()
    networks: tuple[int, ...] = ()

    def __post_init__(self):
        if not (0.0 < self.max_rate_hz <= 10000.0):
            raise ConfigError(f"RecordConfig.max_rate_hz = {self.max_rate_hz:g}: must be in (0, 10000] Hz "
                              "(--record-max-rate-hz)")
        if not self.max_mb > 0:
            raise ConfigError(f"RecordConfig.max_mb = {self.max_mb:g}: must be > 0 (--record-max-mb)")
        if self.train_last_s < 0:
            raise ConfigError(f"RecordConfig.train_last_s = {self.train_last_s:g}: must be >= 0 s (--record-train-s)")
        if any(int(e) < 1 for e in self.epochs):
            raise ConfigError(f"RecordConfig.epochs = {self.epochs}: epochs are counted from 1 (--record-epochs)")
        if any(int(k) < 0 for k in self.networks):
            raise ConfigError(f"RecordConfig.networks = {self.networks}: indices are >= 0 (--record-networks)")

    def capacity(self, n_all: int, window_ms: float) -> int:
        """Slots of one network's buffer for a window of ``window_ms``: ceil(max_rate_hz x n_all x s)."""
        return max(1, math.ceil(self.max_rate_hz * n_all * window_ms / 1000.0 - 1e-9))

    def recorded_epochs(self, n_epochs: int) -> tuple[int, ...]:
        """The 1-based epochs whose last seconds are recorded (none when ``train_last_s`` is 0)."""
        if self.train_last_s <= 0:
            return ()
        epochs = tuple(sorted({int(e) for e in self.epochs})) or (n_epochs,)
        bad = [e for e in epochs if e > n_epochs]
        if bad:
            raise ConfigError(f"--record-epochs {' '.join(map(str, bad))}: the run has {n_epochs} epochs")
        return epochs


class SpikeBuffer(NamedTuple):
    """A window's spikes of one network (batch axes in front under ``vmap``), as non-zero 32-bit words."""

    word: jnp.ndarray    # (capacity,) uint32: interval of the window x words per interval + word index; unused 0
    bits: jnp.ndarray    # (capacity,) uint32: bit b = a spike at flat index 32 x word index + b of the interval
    used: jnp.ndarray    # () int32 slots the window needed (> capacity: the rest were not written)
    count: jnp.ndarray   # () int32 spikes in the window


class Recording(NamedTuple):
    """A recorded window: its spikes, the network's own spike count per cell over it, and the arm every 10 ms (row i
    is the state after interval i of the window, at window start + (i + 1) x 10 ms)."""

    spikes: SpikeBuffer
    counts: jnp.ndarray       # (n_all,) int32 spikes per cell in the window, as the network counted them
    hand_m: jnp.ndarray       # (W, 2) m
    q_rad: jnp.ndarray        # (W, 2) rad
    u: jnp.ndarray            # (W, 4) excitations sent to the arm
    muscles: Any = None       # MuscleObs of (W, 22) arrays (musculoskeletal arm), else None


def empty(capacity: int) -> SpikeBuffer:
    """A spike buffer of ``capacity`` slots (8 bytes each), nothing recorded."""
    zeros = jnp.zeros((capacity,), jnp.uint32)
    return SpikeBuffer(word=zeros, bits=zeros, used=jnp.zeros((), jnp.int32), count=jnp.zeros((), jnp.int32))


def words_per_interval(steps: int, n_all: int) -> int:
    """32-bit words that hold one interval's spike bits: ``steps`` network steps x ``n_all`` cells, rounded up."""
    return -(-steps * n_all // WORD_BITS)


def push(buf: SpikeBuffer, spikes, interval) -> SpikeBuffer:
    """Append the (steps, n_all) bool block of the window's interval number ``interval`` (int32): its non-zero
    32-bit words, in order. Slots past the capacity are dropped by the scatter and counted in ``used``."""
    steps, n_all = spikes.shape
    wpi = words_per_interval(steps, n_all)
    flat = jnp.pad(spikes.reshape(-1), (0, wpi * WORD_BITS - steps * n_all)).reshape(wpi, WORD_BITS)
    bits = jnp.sum(flat.astype(jnp.uint32) << jnp.arange(WORD_BITS, dtype=jnp.uint32), axis=1, dtype=jnp.uint32)
    nonzero = bits != 0
    capacity = buf.word.shape[0]
    index = jnp.where(nonzero, buf.used + jnp.cumsum(nonzero, dtype=jnp.int32) - 1, capacity)   # capacity: dropped
    codes = interval.astype(jnp.uint32) * jnp.uint32(wpi) + jnp.arange(wpi, dtype=jnp.uint32)
    return SpikeBuffer(word=buf.word.at[index].set(codes, mode="drop"), bits=buf.bits.at[index].set(bits, mode="drop"),
                       used=buf.used + jnp.sum(nonzero, dtype=jnp.int32),
                       count=buf.count + jnp.sum(spikes, dtype=jnp.int32))


def check_window(n_all: int, steps_per_interval: int, intervals: int, what: str) -> None:
    """Raise :class:`ConfigError` (naming ``what``) unless a window of ``intervals`` intervals of
    ``steps_per_interval`` steps over ``n_all`` cells can be addressed by a uint32 word code."""
    if intervals * words_per_interval(steps_per_interval, n_all) >= MAX_CODES:
        raise ConfigError(f"{what}: {intervals} intervals x {steps_per_interval} steps x {n_all} cells do not fit "
                          "a uint32 word code; record a shorter window")


def batch_bytes(n_networks: int, capacity: int) -> int:
    """Bytes of the spike buffers of ``n_networks`` networks of ``capacity`` slots each."""
    return n_networks * capacity * BYTES_PER_SLOT


def check_memory(config: RecordConfig, n_networks: int, windows: dict[str, int]) -> dict:
    """Refuse buffers above ``config.max_mb``. ``windows``: name -> capacity per network. Returns the bound as a
    dict (bytes on the device for the largest window, bytes kept on the host for all of them)."""
    device = max(batch_bytes(n_networks, c) for c in windows.values())
    host = sum(batch_bytes(n_networks, c) for c in windows.values())
    if max(device, host) > config.max_mb * 1e6:
        worst = max(windows, key=windows.get)
        raise ConfigError(f"--record-spikes: the spike buffers need {max(device, host) / 1e6:.0f} MB ({n_networks} "
                          f"networks x {windows[worst]} slots x {BYTES_PER_SLOT} B for the {worst} window; capacity "
                          f"= --record-max-rate-hz {config.max_rate_hz:g} Hz x cells x window s), above "
                          f"--record-max-mb {config.max_mb:g}: record fewer seconds or networks, lower the rate bound "
                          "or raise the limit")
    return {"device_bytes": device, "host_bytes": host, "bytes_per_slot": BYTES_PER_SLOT}


def check_overflow(buffer: SpikeBuffer, capacity: int, seeds, what: str, max_rate_hz: float) -> None:
    """Fail if any network's window needed more slots than its buffer: an error naming the capacity and its bound."""
    used = np.asarray(buffer.used).reshape(-1)[: len(seeds)]
    count = np.asarray(buffer.count).reshape(-1)
    bad = np.nonzero(used > capacity)[0]
    if bad.size:
        nets = ", ".join(f"{seeds[i]} ({int(count[i])} spikes in {int(used[i])} slots)" for i in bad[:10])
        raise RuntimeError(f"spike record of the {what}: network(s) of seed {nets} fired more than the buffer's "
                           f"capacity of {capacity} slots (--record-max-rate-hz {max_rate_hz:g} Hz x cells x window "
                           "s); raise --record-max-rate-hz")


def decode(word, bits, used, n_all: int, start_step: int, steps_per_interval: int) -> tuple[np.ndarray, np.ndarray]:
    """(step, cell) of one network's recorded window, ordered by step then cell: clock steps since the start of
    the run (a spike at step s happened in ((s - 1) dt, s dt]), global cell ids."""
    n = min(int(used), len(word))
    wpi = words_per_interval(steps_per_interval, n_all)
    interval, k = np.divmod(np.asarray(word)[:n].astype(np.int64), wpi)
    on = (np.asarray(bits)[:n].astype(np.uint64)[:, None] >> np.arange(WORD_BITS, dtype=np.uint64)) & np.uint64(1)
    slot, bit = np.nonzero(on)
    step_in, cell = np.divmod(k[slot] * WORD_BITS + bit, n_all)
    return ((start_step + 1 + interval[slot] * steps_per_interval + step_in).astype(np.int32),
            cell.astype(np.int16))
