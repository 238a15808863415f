"""The authors' musculoskeletal arm: 2 hinges in the horizontal plane, 22 Schutte-1993 muscles, 4 driven groups.

One step advances ``config.dt_s`` (1 ms by default) of simulated time (SI units throughout):

1. the 4 group excitations are spread over the driven muscles ([model: the musculoskeletal
   arm](../model.md#the-musculoskeletal-arm); passive muscles get none);
2. each muscle's activation and fibre length advance along the muscle-tendon length extrapolated from the current
   length and its rate (moment arms times joint velocities) (:mod:`jaxarm.arm.muscle`): the fibre ODE is stiff and
   kinked where a tendon goes slack, and one 1 ms linearly-implicit step of it chatters. By default
   (``config.muscle_integrator="backward_euler"``) in one fully implicit step solved by
   ``config.muscle_newton_iterations`` Newton iterations; with ``"linearly_implicit"`` in
   ``config.muscle_substeps`` linearly-implicit steps (0.1 ms for 10, the authors' integrator step; see
   ``MusculoskeletalArmConfig.muscle_substeps``);
3. the tendon forces averaged over those muscle steps (backward Euler: at the step's midpoint) times the moment arms
   give joint torques; beyond the joint ranges a penalty spring-damper adds limit torques (the original's joint-limit
   force subsystem; MuJoCo's constraint solver stays off);
4. semi-implicit Euler on the skeleton with the mass matrix and velocity-product torques of the geometry backend,
   the limit damping taken implicitly.

``config.smooth`` replaces every kink of the muscles and of the joint limits by a C-infinity version of a stated
width (``jaxarm.config.arm.SMOOTH_KINKS``; the widths are
:mod:`jaxarm.arm.muscle`'s ``W_*`` and :data:`W_JOINT_LIMIT_RAD`): the arm to differentiate through.

The arm computes in JAX's default float type (float32; float64 under ``jax.enable_x64``, which the
finite-difference checks of its gradient use); its fitted constants are float32 either way.

The geometry backend is MJX (``backend="mjx"``, the reference) or the fitted fast path (``backend="fast"``); the
muscle, the limits and the integrator are this one module, shared by both.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.arm import muscle as mus
from jaxarm.arm.base import ArmObs, MuscleObs, hand_position
from jaxarm.arm.geometry import FastGeometry, MjxGeometry, c_geometry, load_mjmodel
from jaxarm.config.arm import SMOOTH_KINKS, MusculoskeletalArmConfig
from jaxarm.cpu_arithmetic import ordered_dot

#: Muscles driven by each excitation group ([model: the musculoskeletal arm](../model.md#the-musculoskeletal-arm),
#: MuscleExcitationSetter). Others are passive.
GROUP_MUSCLES = (
    ("DELT3", "Infraspinatus", "Latissimus_dorsi_1", "Latissimus_dorsi_2", "Latissimus_dorsi_3", "Teres_minor"),
    ("PECM1", "PECM2", "PECM3", "DELT1", "Coracobrachialis"),
    ("TRIlong", "TRIlat", "TRImed"),
    ("BIClong", "BICshort", "BRA"),
)
#: Muscles whose fibre lengths feed the proprioceptive population, in group order ([model: the musculoskeletal
#: arm](../model.md#the-musculoskeletal-arm), muscleLengthBranch).
PROPRIO_MUSCLES = ("DELT3", "PECM1", "TRIlong", "BIClong")


#: The muscle state is held in a multiple of this many lanes (8 float32 lanes = one AVX register): XLA:CPU
#: vectorises the muscle's element-wise loops only when the muscle axis fills whole registers, and the 22
#: muscles padded to 24 ran the muscle step 2.5x faster per muscle (``benchmarks/arm.py``, docs in README).
MUSCLE_LANES = 8

#: Joint-angle overshoot (rad) over which the smooth limit spring takes up and the limit damping switches on.
W_JOINT_LIMIT_RAD = 1e-3


class MusculoskeletalArmState(NamedTuple):
    q: jnp.ndarray      # (2,) rad
    qd: jnp.ndarray     # (2,) rad/s
    muscle: mus.MuscleState  # (n_lanes,) each: the 22 muscles in osim order, then inert padding lanes


class MusculoskeletalArm:
    """``init / step / observe`` plus the muscle geometry queries ``mtu_lengths`` and ``moment_arms``.

    The state's muscle arrays have ``n_lanes`` entries (24 for the 22 muscles, see ``MUSCLE_LANES``); the padding
    lanes are inert. :meth:`observe` returns the 22 muscles only.
    """

    kind = "musculoskeletal"

    def __init__(self, backend: str = "fast", config: MusculoskeletalArmConfig | None = None):
        self.config = config = config or MusculoskeletalArmConfig()
        self.backend = backend
        self.dt_s = config.dt_s
        self.smooth = SMOOTH_KINKS if config.smooth is True else tuple(config.smooth or ())
        self.geometry = MjxGeometry() if backend == "mjx" else FastGeometry()
        table = mus.load_muscle_table()
        self.muscle_names = tuple(m["name"] for m in table)
        if tuple(self.geometry.names) != self.muscle_names:
            raise ValueError("arm assets disagree: tendon order in the geometry differs from muscles.json; "
                             "regenerate with `python -m jaxarm.arm.convert` and `python -m jaxarm.arm.fit`")
        params = mus.make_muscle_params(table, time_scale_s=config.time_scale_s, activation1=config.activation1,
                                        activation2=config.activation2, damping_override=config.damping)
        # Muscle-tendon lengths at the start posture from MuJoCo's C library: both backends relax the same muscles.
        lmt0 = c_geometry(load_mjmodel(), np.asarray(config.start_posture_rad)).mtu_length_m
        self.tendon_slack_stored_m = np.asarray(params.tendon_slack_length_m)
        if config.relax_at_start:
            params = params._replace(tendon_slack_length_m=jnp.asarray(
                relaxed_tendon_slack(params, lmt0), jnp.float32))
        self.params = params
        # Padding lanes are copies of muscle 0 that get no excitation and pull on nothing (zero moment arms):
        # they only keep the muscle arrays a whole number of SIMD registers wide.
        self.n_muscles = n = len(table)
        self.n_lanes = -(-n // MUSCLE_LANES) * MUSCLE_LANES
        self._pad = np.concatenate([np.arange(n), np.zeros(self.n_lanes - n, int)])
        def lanes(v):
            if isinstance(v, mus.Spline):  # a curve shared by all muscles is stored once
                return v if v.knots.shape[0] == 1 else mus.Spline(*(jnp.asarray(np.asarray(a)[self._pad]) for a in v))
            return jnp.asarray(np.asarray(v)[self._pad])

        self.lane_params = mus.MuscleParams(*(lanes(v) for v in params))

        index = {n: i for i, n in enumerate(self.muscle_names)}
        drive = np.zeros((self.n_lanes, 4), np.float32)
        for g, names in enumerate(GROUP_MUSCLES):
            drive[[index[n] for n in names], g] = 1.0
        self.group_drive = jnp.asarray(drive)   # (lanes, 4) excitation of each muscle lane from the 4 groups
        self.proprio_index = jnp.asarray([index[n] for n in PROPRIO_MUSCLES])
        self._q_min = jnp.asarray(config.q_min_rad, jnp.float32)
        self._q_max = jnp.asarray(config.q_max_rad, jnp.float32)
        self._k_limit = jnp.asarray(config.joint_limit_stiffness_nm_per_rad, jnp.float32)
        self._b_limit = jnp.asarray(config.joint_limit_damping_nms_per_rad, jnp.float32)

    # -- geometry queries ------------------------------------------------------------------------------------
    def mtu_lengths(self, q):
        """(22,) muscle-tendon lengths, m, at joint angles q (rad)."""
        q = jnp.asarray(q, float)
        return self.geometry(q, jnp.zeros(2, q.dtype)).mtu_length_m

    def moment_arms(self, q):
        """(22, 2) moment arms, m (positive = tension flexes that joint)."""
        q = jnp.asarray(q, float)
        return self.geometry(q, jnp.zeros(2, q.dtype)).moment_arm_m

    # -- dynamics ----------------------------------------------------------------------------------------------
    def init(self, q0=None) -> MusculoskeletalArmState:
        """At rest at q0 (rad; default the start posture), unexcited muscles in force equilibrium."""
        q0 = jnp.asarray(self.config.start_posture_rad if q0 is None else q0, float)
        lmt = self._lanes(self.mtu_lengths(q0))
        activation = jnp.zeros_like(lmt)
        lm = mus.equilibrium_fiber_length(self.lane_params, activation, lmt, smooth=self.smooth)
        return MusculoskeletalArmState(q0, jnp.zeros(2, q0.dtype), mus.MuscleState(activation, lm))

    def _lanes(self, per_muscle):
        """(22, ...) -> (n_lanes, ...): padding lanes repeat muscle 0."""
        if self.n_lanes == self.n_muscles:
            return per_muscle
        return jnp.concatenate([per_muscle, jnp.broadcast_to(per_muscle[:1], (self.n_lanes - self.n_muscles,)
                                                             + per_muscle.shape[1:])])

    def excitations(self, u):
        """(n_lanes,) muscle excitations (the 22 muscles, then zeros for the padding lanes) from the 4 group
        excitations u in [0, 1] (values outside are clipped)."""
        return ordered_dot(self.group_drive, jnp.clip(jnp.asarray(u, float), 0.0, 1.0))

    def step(self, state: MusculoskeletalArmState, u) -> MusculoskeletalArmState:
        """u: (4,) excitations (sh-ext, sh-flex, el-ext, el-flex) in [0, 1]. Advances ``dt_s`` (1 ms default)."""
        e = self.excitations(u)
        h = self.config.dt_s / self.config.substeps

        def substep(s, _):
            return self._substep(s, e, h), None

        state, _ = jax.lax.scan(substep, state, None, length=self.config.substeps)
        return state

    def joint_limit_torque(self, q, qd):
        """Penalty torque (N m) beyond the joint range: spring on the overshoot; the damping inside the limit zone is returned
        separately as a coefficient (N m s/rad) so the integrator can take it implicitly."""
        below, above = self._q_min - q, q - self._q_max
        if "joint_limits" in self.smooth:
            spring = self._k_limit * (mus.soft_max0(below, W_JOINT_LIMIT_RAD) - mus.soft_max0(above, W_JOINT_LIMIT_RAD))
            zone = jax.nn.sigmoid(below / W_JOINT_LIMIT_RAD) + jax.nn.sigmoid(above / W_JOINT_LIMIT_RAD)
            return spring, self._b_limit * zone
        spring = self._k_limit * (jnp.maximum(below, 0.0) - jnp.maximum(above, 0.0))
        return spring, jnp.where((below > 0) | (above > 0), self._b_limit, 0.0)

    def _muscles(self, muscle: mus.MuscleState, e, lmt0, lmt_rate, h):
        """The muscles over ``h`` s along lmt0 + lmt_rate t (m, m/s): ``muscle_substeps`` linearly-implicit steps, or
        one backward-Euler step. Returns the new muscle state and the mean tendon force (N) over the step (the
        impulse the skeleton receives): the mean of the sub-steps' end forces, or (backward Euler) the force at the
        step's midpoint."""
        if self.config.muscle_integrator == "backward_euler":
            lmt = lmt0 + lmt_rate * h
            stepped = mus.step_backward_euler(self.lane_params, muscle, e, lmt0, lmt, h,
                                              self.config.muscle_newton_iterations, self.smooth)
            # The impulse over the step by the midpoint rule: the tendon force at the mean of the start and end fibre
            # lengths and path lengths (the end's force alone lags by half a step: 0.17 deg median path error on
            # 10 ms-held excitations against 0.11 for the midpoint, experiments/arm_convergence.py).
            mid_fiber = 0.5 * (muscle.fiber_length_m + stepped.fiber_length_m)
            return stepped, mus.tendon_force(self.lane_params, mid_fiber, lmt0 + lmt_rate * (0.5 * h), self.smooth)
        k = self.config.muscle_substeps
        hk = h / k

        def body(carry, i):
            ms, total = carry
            lmt = lmt0 + lmt_rate * ((i + 1.0) * hk)
            ms = mus.step(self.lane_params, ms, e, lmt, hk, self.smooth)
            return (ms, total + mus.tendon_force(self.lane_params, ms.fiber_length_m, lmt, self.smooth)), None

        (muscle, total), _ = jax.lax.scan(body, (muscle, jnp.zeros_like(lmt0)), jnp.arange(k, dtype=lmt0.dtype))
        return muscle, total * (1.0 / k)

    def _substep(self, s: MusculoskeletalArmState, e, h) -> MusculoskeletalArmState:
        geo = self.geometry(s.q, s.qd)
        lmt = self._lanes(geo.mtu_length_m)
        lmt_rate = self._lanes(-ordered_dot(geo.moment_arm_m, s.qd))      # dL/dt = -(moment arm) . qd
        ms, tendon = self._muscles(s.muscle, e, lmt, lmt_rate, h)
        tendon = tendon[: self.n_muscles]
        spring, damping = self.joint_limit_torque(s.q, s.qd)
        tau = ordered_dot(geo.moment_arm_m.T, tendon) + spring - geo.bias_nm
        # (M + h B) qd' = M qd + h tau: implicit limit damping B = diag(damping).
        qd = solve_2x2(geo.mass_matrix + h * jnp.diag(damping), ordered_dot(geo.mass_matrix, s.qd) + h * tau)
        return MusculoskeletalArmState(s.q + h * qd, qd, ms)

    def observe(self, state: MusculoskeletalArmState) -> ArmObs:
        lmt = self.mtu_lengths(state.q)
        m = self.n_muscles
        real = mus.MuscleState(state.muscle.activation[:m], state.muscle.fiber_length_m[:m])
        f = mus.forces(self.params, real, lmt, self.smooth)
        lm = real.fiber_length_m
        muscles = MuscleObs(activation=real.activation, active_force_n=f.active_force_n,
                            passive_force_n=f.passive_force_n, force_n=f.tendon_force_n,
                            fiber_length_m=lm, mtu_length_m=lmt)
        return ArmObs(q=state.q, qd=state.qd, hand=hand_position(state.q, self.config.segments_m),
                      proprio=lm[self.proprio_index], muscles=muscles)


def solve_2x2(a, b):
    """Closed-form solve of a 2x2 system (a batched LAPACK call costs far more than these few flops)."""
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return jnp.stack([a[1, 1] * b[0] - a[0, 1] * b[1], a[0, 0] * b[1] - a[1, 0] * b[0]]) / det


def relaxed_tendon_slack(params: mus.MuscleParams, lmt0) -> np.ndarray:
    """Tendon slack lengths (m) after the start-posture relaxation rule (see ``MusculoskeletalArmConfig``).

    A muscle whose path at the start posture is longer than an optimal-length fibre plus its stored tendon slack
    length would be stretched there; its slack length grows to ``lmt0 - l_opt cos(alpha0)`` so that the fibre rests
    at optimal length (zero passive force in the stored curves) with a just-slack tendon. Others are unchanged.
    """
    lopt = np.asarray(params.optimal_fiber_length_m, float)
    resting_span = lopt * np.cos(np.asarray(params.pennation_rad, float))
    return np.maximum(np.asarray(params.tendon_slack_length_m, float), np.asarray(lmt0, float) - resting_span)


def make_musculoskeletal_arm(backend: str = "fast", config: MusculoskeletalArmConfig | None = None):
    return MusculoskeletalArm(backend, config)
