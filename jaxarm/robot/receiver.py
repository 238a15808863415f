"""The Network System: the robot's UDP receiver, one call per 2 ms tick (libbarrett ``ex11_master_master.h``
semantics, wam.md §4), with the safety envelope of :mod:`jaxarm.robot.safety` between it and the controller.

Pure functions of (config, state, inputs) returning a new state; the state is a NamedTuple. Units: rad, s.

Every tick gets the datagrams that arrived since the previous one (at most ``ReceiverConfig.max_reads_per_tick``
are read from the socket). Only the newest ``max_judged_per_tick`` are judged, in arrival order; older ones are
counted ``flood_dropped``, which bounds the work per tick under a flood while the newest valid packet still wins.
Each judged datagram is accepted or rejected for exactly one reason, each with its own counter
(:data:`REJECTION_KINDS`):

* ``raw_refused``: a headerless libbarrett packet (any 16 or 32 bytes without the magic, whatever they hold)
  while ``SafetyConfig.accept_raw`` is off (the default);
* ``oversize`` / ``malformed`` / ``truncated`` / ``nonfinite``: decoding failed (:mod:`jaxarm.robot.protocol`);
* ``duplicate``: same sequence number as the held target;
* ``out_of_order``: older sequence number than the held target (serial-number arithmetic mod 2**32, so the
  sequence wraps from 2**32 - 1 to 0 without a rejection);
* ``stale``: newer sequence number but a simulated time older than the held target's by more than
  ``ReceiverConfig.stale_after_s`` (a replayed or restarted sender);
* ``out_of_range`` / ``nonfinite`` / ``jump``: the target fails the envelope (:func:`jaxarm.robot.safety.check_target`).

Accepted packets count as ``ok``; those clamped by the envelope also as ``clamped``; accepted packets overtaken
within the same tick also as ``superseded``. A raw packet (no sequence number) clears the sequence tracking.

Holds (the robot's target becomes where it is, :data:`HOLD_TIMEOUT` / :data:`HOLD_REJECTIONS` in ``hold``):

* no accepted packet for ``ReceiverConfig.timeout_s`` -> one ``timeouts`` count (with ``on_timeout =
  "hold_target"`` the last target is kept instead);
* ``SafetyConfig.max_consecutive_rejections`` rejected datagrams in a row -> one ``rejection_holds`` count.

Either hold unlinks: the sequence tracking is forgotten, and the next valid packet is accepted whatever its
number (as after a sender restart) and is only range-checked (no jump check against a stream that has stopped).
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import numpy as np

from jaxarm.robot import safety
from jaxarm.robot.config import WamSimConfig
from jaxarm.robot.protocol import SEQ_MODULUS, DecodeError, decode, is_raw

#: Why a judged datagram was not used; each reason has its own counter, log column and summary entry.
REJECTION_KINDS = ("oversize", "malformed", "truncated", "nonfinite", "raw_refused", "duplicate", "out_of_order",
                   "stale", "out_of_range", "jump")
#: Values of ``ReceiverState.hold`` (and of the log's ``hold`` column).
FOLLOWING, HOLD_TIMEOUT, HOLD_REJECTIONS = 0, 1, 2


class Counters(NamedTuple):
    """Cumulative datagram counts. ``received = ok + rejected + flood_dropped`` always holds."""

    received: int = 0          # datagrams handed to the receiver
    ok: int = 0                # accepted (clamped ones included)
    clamped: int = 0           # accepted after clamping into the allowed range
    superseded: int = 0        # accepted but overtaken by a newer accepted packet in the same tick
    flood_dropped: int = 0     # not judged: older than the newest max_judged_per_tick of their tick
    oversize: int = 0
    malformed: int = 0
    truncated: int = 0
    nonfinite: int = 0
    raw_refused: int = 0
    duplicate: int = 0
    out_of_order: int = 0
    stale: int = 0
    out_of_range: int = 0
    jump: int = 0
    timeouts: int = 0          # holds after timeout_s without an accepted packet
    rejection_holds: int = 0   # holds after max_consecutive_rejections rejections in a row

    @property
    def rejected(self) -> int:
        return sum(getattr(self, k) for k in REJECTION_KINDS)


class ReceiverState(NamedTuple):
    target: np.ndarray               # (4,) WAM joint target the controller follows, rad
    seq: Optional[int]               # sequence number of the held target (None: unlinked or raw)
    t: Optional[float]               # sender's simulated time of the held target, s (None: unlinked or raw)
    last_accept_s: Optional[float]   # robot time of the last accepted packet, s (None: never)
    linked: bool                     # a packet was accepted and no hold since
    rejections_in_row: int           # rejected datagrams since the last accepted one
    last_rejection: str              # reason of the latest rejection ("" before any)
    hold: int                        # FOLLOWING, HOLD_TIMEOUT or HOLD_REJECTIONS
    counters: Counters


def receiver_init(target: np.ndarray) -> ReceiverState:
    return ReceiverState(np.asarray(target, dtype=float).copy(), None, None, None, False, 0, "", FOLLOWING,
                         Counters())


def _count(c: Counters, kind: str, n: int = 1) -> Counters:
    return c._replace(**{kind: getattr(c, kind) + n})


def _reject(state: ReceiverState, kind: str) -> tuple[ReceiverState, str]:
    return state._replace(counters=_count(state.counters, kind), rejections_in_row=state.rejections_in_row + 1,
                          last_rejection=kind), kind


def judge(config: WamSimConfig, env: safety.Envelope, state: ReceiverState, data: bytes,
          now_s: float) -> tuple[ReceiverState, str]:
    """Judge one datagram arriving at robot time ``now_s`` (s); return the new state and the verdict (``"ok"``,
    ``"clamped"`` or one of :data:`REJECTION_KINDS`). Does not count ``received`` (:func:`receive` does)."""
    raw = is_raw(data)
    if raw and not config.safety.accept_raw:   # refused whatever it holds, before decoding
        return _reject(state, "raw_refused")
    try:
        packet = decode(data)
    except DecodeError as err:
        return _reject(state, err.kind)
    in_sequence = state.linked and state.seq is not None and not raw
    if in_sequence:
        diff = (packet.seq - state.seq) % SEQ_MODULUS
        if diff == 0:
            return _reject(state, "duplicate")
        if diff >= SEQ_MODULUS // 2:
            return _reject(state, "out_of_order")
        if packet.t < state.t - config.receiver.stale_after_s:
            return _reject(state, "stale")
    angles = np.asarray(packet.angles, dtype=float)
    target = config.joint_map.to_wam(angles) if angles.size == 2 else angles
    last, dt = None, 0.0
    if state.linked:
        sender_elapsed = packet.t - state.t if in_sequence else None
        last, dt = state.target, safety.jump_dt(env, now_s - state.last_accept_s, sender_elapsed)
    verdict, target = safety.check_target(env, target, last, dt)
    if verdict not in safety.ACCEPTED:
        return _reject(state, verdict)
    c = _count(state.counters, "ok")
    if verdict == "clamped":
        c = _count(c, "clamped")
    return ReceiverState(target, packet.seq, packet.t, now_s, True, 0, state.last_rejection, FOLLOWING, c), verdict


def _hold(config: WamSimConfig, env: safety.Envelope, state: ReceiverState, q: np.ndarray, kind: int,
          counter: str) -> ReceiverState:
    target = state.target
    if kind == HOLD_REJECTIONS or config.receiver.on_timeout == "hold_position":
        target = np.minimum(np.maximum(np.asarray(q, dtype=float), env.lo), env.hi)
    return state._replace(target=target, seq=None, t=None, linked=False, hold=kind,
                          counters=_count(state.counters, counter))


def receive(config: WamSimConfig, env: safety.Envelope, state: ReceiverState, datagrams, now_s: float,
            q: np.ndarray) -> tuple[ReceiverState, int]:
    """One tick of the Network System at robot time ``now_s`` (s) with the robot at ``q`` (rad): judge the
    newest datagrams that arrived since the last tick, keep the newest accepted target, handle holds. Returns
    the new state and the number of packets accepted this tick."""
    datagrams = list(datagrams)
    n = len(datagrams)
    if n:
        keep = config.receiver.max_judged_per_tick
        c = _count(state.counters, "received", n)
        if n > keep:
            c = _count(c, "flood_dropped", n - keep)
            datagrams = datagrams[n - keep:]
        state = state._replace(counters=c)
    accepted = 0
    limit = config.safety.max_consecutive_rejections
    for data in datagrams:
        state, verdict = judge(config, env, state, data, now_s)
        if verdict in safety.ACCEPTED:
            accepted += 1
        elif state.rejections_in_row == limit:
            state = _hold(config, env, state, q, HOLD_REJECTIONS, "rejection_holds")
    if accepted > 1:
        state = state._replace(counters=_count(state.counters, "superseded", accepted - 1))
    if not accepted and state.linked and now_s - state.last_accept_s >= config.receiver.timeout_s - 1e-12:
        state = _hold(config, env, state, q, HOLD_TIMEOUT, "timeouts")
    return state, accepted
