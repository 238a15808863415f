"""The authors' simple kinematic arm ([model: the arms](../model.md#the-arms), arminterface_pipe.py "dummyArm").

Each step is one 10 ms update of the original loop: the joint angle moves by gain x (flexor - extensor excitation);
muscle lengths are a linear map of the joint angles. No dynamics, no muscles.
"""
from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from jaxarm.arm.base import ArmObs, hand_position
from jaxarm.config.arm import START_POSTURE_RAD, SimpleArmConfig


class SimpleArmState(NamedTuple):
    q_acc: jnp.ndarray   # (2,) internal angle accumulators, rad (may run past the limits when windup=True)
    q_prev: jnp.ndarray  # (2,) reported angles one update earlier, rad (for the reported velocity)


class SimpleArm:
    """Kinematic arm with ``init / step / observe``. ``step`` advances **10 ms** (the authors' update period)."""

    kind = "simple"
    dt_s = 0.010
    muscle_names: tuple[str, ...] = ()

    def __init__(self, config: SimpleArmConfig = SimpleArmConfig()):
        self.config = config
        self._q_min = jnp.asarray(config.q_min_rad)
        self._q_max = jnp.asarray(config.q_max_rad)

    def init(self, q0=None) -> SimpleArmState:
        """q0: (2,) start angles in rad (default the start posture (0.62, 1.53))."""
        # float32, or float64 under jax.enable_x64 (for float64 references in tests), as the musculoskeletal arm
        q0 = jnp.asarray(START_POSTURE_RAD if q0 is None else q0, dtype=jnp.result_type(float))
        return SimpleArmState(q_acc=q0, q_prev=self._clip(q0))

    def step(self, state: SimpleArmState, u) -> SimpleArmState:
        """u: (4,) excitations (sh-ext, sh-flex, el-ext, el-flex). Advances 10 ms."""
        u = jnp.asarray(u, dtype=jnp.result_type(float))
        dq = self.config.gain_rad * jnp.stack([u[1] - u[0], u[3] - u[2]])
        q_acc = state.q_acc + dq
        if not self.config.windup:
            q_acc = self._clip(q_acc)
        return SimpleArmState(q_acc=q_acc, q_prev=self._clip(state.q_acc))

    def observe(self, state: SimpleArmState) -> ArmObs:
        q = self._clip(state.q_acc)
        return ArmObs(q=q, qd=(q - state.q_prev) / self.dt_s, hand=hand_position(q, self.config.segments_m),
                      proprio=self.proprio_lengths(q))

    def proprio_lengths(self, q):
        """(4,) lengths (sh-ext, sh-flex, el-ext, el-flex), m: L_ext = lo + span x, L_flex = lo + span (1 - x)."""
        lo, hi = self.config.proprio_range_m
        x = (q - self._q_min) / (self._q_max - self._q_min)
        ext, flex = lo + (hi - lo) * x, lo + (hi - lo) * (1.0 - x)
        return jnp.stack([ext[0], flex[0], ext[1], flex[1]])

    def _clip(self, q):
        return jnp.clip(q, self._q_min, self._q_max)
