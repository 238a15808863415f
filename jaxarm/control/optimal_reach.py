"""Optimal-control reference reaches: the best reach the musculoskeletal arm can make to a target.

The four muscle-group excitations (sh-ext, sh-flex, el-ext, el-flex) over ``duration_s`` are optimised by gradient
descent (optax Adam) through the differentiable arm (``make_arm("musculoskeletal", smooth=True)``: the gradient of
the piecewise-smooth arm over a whole reach is not trustworthy, ``docs/gradients.md``). The excitation of each group
is a piecewise-linear curve through ``knots`` values, each the logistic of a free parameter (so in (0, 1) without a
clip to differentiate through), interpolated at every arm step.

Two costs, both in SI units and both with the hand at rest at the end:

* ``"min-effort"``: mean squared excitation over the reach (effort, dimensionless) + ``endpoint_weight`` x (mean
  squared hand-target distance over the last ``hold_s``, m²) + ``rest_weight`` x (mean squared hand speed over the
  last ``hold_s``, m²/s²). The hand must be at the target and still by ``duration_s - hold_s``; it gets there by the
  cheapest excitations.
* ``"min-time"``: the mean over the whole reach of the hand-target distance (m) beyond ``radius_m`` softened, plus
  the same rest term at the end and a small effort term: the hand goes as fast as the arm allows and stays.

The whole optimisation is one compiled program (``lax.scan`` over Adam iterations, each a ``jax.value_and_grad``
through a ``lax.scan`` over arm steps).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from jaxarm.config.validate import check_choice, check_range

COSTS = ("min-effort", "min-time")
#: The min-time cost counts distance in this unit (cm), so that it is of the same order as the rest term.
_MIN_TIME_DISTANCE_UNIT_M = 0.01


@dataclass(frozen=True)
class OptimalReachConfig:
    """Static configuration of one optimal-reach problem.

    Attributes:
        cost: ``"min-effort"`` or ``"min-time"`` (module docstring).
        duration_s: length of the reach, s.
        hold_s: final stretch over which the hand must be at the target and at rest, s.
        knots: excitation knots per muscle group, evenly spaced over ``duration_s`` (linear between them).
        iterations: Adam steps.
        learning_rate: Adam's step size on the knots' logits.
        endpoint_weight: weight of the mean squared distance (m²) over the hold in ``min-effort``, 1/m².
        rest_weight: weight of the mean squared hand speed (m²/s²) over the hold, s²/m².
        effort_weight: weight of the mean squared excitation in ``min-time`` (``min-effort`` uses 1).
        radius_m: in ``min-time``, distances inside this radius cost (almost) nothing, m.
        initial_excitation: every knot's starting value, in (0, 1).
    """

    cost: str = "min-effort"
    duration_s: float = 1.0
    hold_s: float = 0.3
    knots: int = 21
    iterations: int = 300
    learning_rate: float = 0.1
    endpoint_weight: float = 1e4
    rest_weight: float = 10.0
    effort_weight: float = 0.01
    radius_m: float = 0.01
    initial_excitation: float = 0.05

    def __post_init__(self):
        check_choice(self, "cost", COSTS)
        check_range(self, "duration_s", 0.05, 10.0)
        check_range(self, "hold_s", 0.0, self.duration_s)
        check_range(self, "knots", 2, 1000, integer=True)
        check_range(self, "iterations", 1, 100_000, integer=True)
        check_range(self, "learning_rate", 0.0, 10.0, lo_open=True)
        for name in ("endpoint_weight", "rest_weight", "effort_weight"):
            check_range(self, name, 0.0, 1e9)
        check_range(self, "radius_m", 0.0, 0.5)
        check_range(self, "initial_excitation", 0.0, 1.0, lo_open=True, hi_open=True)


class OptimalReach(NamedTuple):
    """The optimised reach (arrays; NumPy after :func:`optimal_reach`)."""

    excitations: np.ndarray   # (T, 4) muscle-group excitations in [0, 1], one per arm step
    hand_m: np.ndarray        # (T, 2) hand positions, m, after each step
    q_rad: np.ndarray         # (T, 2) joint angles, rad
    muscle_force_n: np.ndarray  # (T, 22) tendon force of each muscle, N
    loss: np.ndarray          # (iterations,) cost before each Adam step
    dt_s: float               # arm step, s


def _interpolation_matrix(knots: int, steps: int) -> np.ndarray:
    """(steps, knots) weights of piecewise-linear interpolation from evenly spaced knots to every step."""
    t = (np.arange(steps) + 1.0) / steps * (knots - 1)
    lo = np.minimum(np.floor(t).astype(int), knots - 2)
    frac = t - lo
    w = np.zeros((steps, knots), np.float32)
    w[np.arange(steps), lo] = 1.0 - frac
    w[np.arange(steps), lo + 1] = frac
    return w


def make_optimal_reach(config: OptimalReachConfig, arm=None):
    """Build the optimiser for ``config``: returns ``reach(target_xy_m) -> OptimalReach``, compiled once (the target
    is traced, so every target reuses the program). ``arm``: default the smooth fast musculoskeletal arm."""
    if arm is None:
        from jaxarm.arm import make_arm
        arm = make_arm("musculoskeletal", smooth=True)
    steps = int(round(config.duration_s / arm.dt_s))
    hold = max(1, int(round(config.hold_s / arm.dt_s)))
    interp = jnp.asarray(_interpolation_matrix(config.knots, steps))
    optimiser = optax.adam(config.learning_rate)

    def excitations_of(logits):
        return interp @ jax.nn.sigmoid(logits)          # (T, 4) in (0, 1)

    def rollout(logits):
        us = excitations_of(logits)

        def body(s, u):
            s = arm.step(s, u)
            obs = arm.observe(s)
            return s, (obs.hand, s.q, obs.muscles.force_n)
        _, (hand, q, force) = jax.lax.scan(body, arm.init(), us)
        return us, hand, q, force

    def cost(logits, target_xy):
        us, hand, _, _ = rollout(logits)
        dist2 = jnp.sum((hand - target_xy) ** 2, axis=-1)
        speed2 = jnp.sum(jnp.diff(hand[-hold - 1:], axis=0) ** 2, axis=-1) / arm.dt_s**2
        effort = jnp.mean(us**2)
        rest = config.rest_weight * jnp.mean(speed2)
        if config.cost == "min-effort":
            return effort + config.endpoint_weight * jnp.mean(dist2[-hold:]) + rest
        # Softened distance beyond the radius: sqrt(d² + r²) - r is ~d far away and ~0 inside.
        r = config.radius_m
        far = jnp.sqrt(dist2 + r * r) - r
        return jnp.mean(far) / _MIN_TIME_DISTANCE_UNIT_M + rest + config.effort_weight * effort

    @jax.jit
    def solve(target_xy):
        target_xy = jnp.asarray(target_xy, jnp.float32)
        logit0 = float(np.log(config.initial_excitation / (1 - config.initial_excitation)))
        logits = jnp.full((config.knots, 4), logit0, jnp.float32)

        def it(carry, _):
            logits, opt = carry
            value, grad = jax.value_and_grad(cost)(logits, target_xy)
            updates, opt = optimiser.update(grad, opt, logits)
            return (optax.apply_updates(logits, updates), opt), value

        (logits, _), losses = jax.lax.scan(it, (logits, optimiser.init(logits)), None, length=config.iterations)
        return logits, losses

    rollout = jax.jit(rollout)

    def reach(target_xy_m) -> OptimalReach:
        logits, losses = solve(jnp.asarray(target_xy_m, jnp.float32))
        us, hand, q, force = rollout(logits)
        return OptimalReach(np.asarray(us), np.asarray(hand), np.asarray(q), np.asarray(force), np.asarray(losses),
                            float(arm.dt_s))
    return reach


def optimal_reach(target_xy_m, config: OptimalReachConfig | None = None, arm=None) -> OptimalReach:
    """The optimised reach to ``target_xy_m`` (2,) m from the arm's start posture (see module docstring).
    ``config``: the problem (default :class:`OptimalReachConfig`); ``arm``: default the smooth fast
    musculoskeletal arm. For several targets, :func:`make_optimal_reach` compiles once."""
    return make_optimal_reach(config or OptimalReachConfig(), arm)(target_xy_m)
