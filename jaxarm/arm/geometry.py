"""Skeleton and muscle-path geometry of the musculoskeletal arm, from two sources behind one signature.

``geometry(q, qd) -> ArmGeometry``: muscle-tendon lengths (m), moment arms (m), the joint-space mass matrix
(kg m^2) and the velocity-product torques (N m) at joint angles q (rad) and velocities qd (rad/s).

* :class:`MjxGeometry` asks MJX: forward kinematics, the spatial tendons through the model's path points, the
  composite-rigid-body mass matrix and the recursive Newton-Euler bias. This is the reference.
* :class:`FastGeometry` evaluates smooth fits of the same quantities made from the same MJCF by
  ``python -m jaxarm.arm.fit``: a bivariate polynomial for each muscle-tendon length (moment arms are its exact
  derivative) and a degree-2 trigonometric polynomial in the elbow angle for the mass matrix, which is exact for
  any two-hinge chain (the kinetic energy is quadratic in the elbow's rotation matrix), with the velocity-product
  torques derived from it by Lagrange's equations.
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm.cpu_arithmetic import ordered_dot

ASSETS = Path(__file__).parent / "assets"
MJCF_PATH = ASSETS / "arm.xml"
FIT_PATH = ASSETS / "fast_fit.npz"
JOINTS = ("shoulder", "elbow")


class ArmGeometry(NamedTuple):
    mtu_length_m: jnp.ndarray    # (M,)
    moment_arm_m: jnp.ndarray    # (M, 2), = -dL/dq: positive when tension drives the joint towards +q (flexion)
    mass_matrix: jnp.ndarray     # (2, 2), kg m^2
    bias_nm: jnp.ndarray         # (2,), velocity-product (Coriolis/centrifugal) torques, N m


def file_sha256(path: Path | str) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_mjmodel(path: Path | str = MJCF_PATH):
    import mujoco

    return mujoco.MjModel.from_xml_path(str(path))


def tendon_names(mjmodel) -> tuple[str, ...]:
    import mujoco

    return tuple(mujoco.mj_id2name(mjmodel, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(mjmodel.ntendon))


def c_geometry(mjmodel, q, qd=(0.0, 0.0)) -> ArmGeometry:
    """The same quantities from MuJoCo's C library (numpy, float64): used to fit and to test."""
    import mujoco

    d = mujoco.MjData(mjmodel)
    d.qpos[:] = q
    d.qvel[:] = qd
    mujoco.mj_forward(mjmodel, d)
    mass = np.zeros((mjmodel.nv, mjmodel.nv))
    mujoco.mj_fullM(mjmodel, d, mass)  # MuJoCo >= 4 signature (m, d, dst)
    ten_j = np.zeros((mjmodel.ntendon, mjmodel.nv))
    if np.asarray(d.ten_J).size == ten_j.size:
        ten_j[:] = np.asarray(d.ten_J).reshape(ten_j.shape)
    else:  # sparse rows (MuJoCo 4 keeps the pattern on the model)
        mujoco.mju_sparse2dense(ten_j, d.ten_J, mjmodel.ten_J_rownnz, mjmodel.ten_J_rowadr, mjmodel.ten_J_colind)
    return ArmGeometry(d.ten_length.copy(), -ten_j, mass, d.qfrc_bias.copy())


class MjxGeometry:
    """Geometry computed by MJX (the reference backend)."""

    def __init__(self, path: Path | str = MJCF_PATH):
        from mujoco import mjx

        self._mjx = mjx
        self.mjmodel = load_mjmodel(path)
        self.model = mjx.put_model(self.mjmodel)
        self._data0 = mjx.make_data(self.model)
        self.names = tendon_names(self.mjmodel)

    def __call__(self, q, qd) -> ArmGeometry:
        mjx, m = self._mjx, self.model
        # MJX computes in the float type its model was put with: float32, or float64 if x64 was on (the
        # finite-difference checks of experiments/arm_gradients.py); the results follow the arm's state
        dtype = self._data0.qpos.dtype
        d = self._data0.replace(qpos=jnp.asarray(q, dtype), qvel=jnp.asarray(qd, dtype))
        d = mjx.kinematics(m, d)
        d = mjx.com_pos(m, d)
        d = mjx.tendon(m, d)
        d = mjx.crb(m, d)
        d = mjx.com_vel(m, d)
        d = mjx.rne(m, d)
        ten_j = _ten_jacobian(d, m.nv, len(self.names))
        out = jnp.result_type(q)
        return ArmGeometry(*(jnp.asarray(x, out) for x in (_ten_length(d), -ten_j, mjx.full_m(m, d), d.qfrc_bias)))


def _ten_length(d):
    return d.ten_length if hasattr(d, "ten_length") else d._impl.ten_length


def _ten_jacobian(d, nv, nten):
    # MuJoCo 4 keeps ten_J on the backend-specific part of Data (direct access is deprecated).
    holder = getattr(d, "_impl", d)
    return jnp.asarray(holder.ten_J).reshape(nten, nv)


# ----------------------------------------------------------------------------------------------------------------
# Fast path


def poly_exponents(degree: int) -> np.ndarray:
    """(K, 2) exponent pairs of all monomials x^i y^j with i + j <= degree."""
    return np.array([(i, t - i) for t in range(degree + 1) for i in range(t + 1)], dtype=np.int32)


def poly_features(x, exponents):
    """Monomials of normalised angles x (..., 2) -> (..., K). Works for numpy and jax arrays."""
    xp = jnp if isinstance(x, jax.Array) else np
    return xp.prod(x[..., None, :] ** exponents, axis=-1)


def trig_features(q2):
    """Degree-2 trigonometric basis in the elbow angle: (1, cos, sin, cos 2, sin 2)."""
    xp = jnp if isinstance(q2, jax.Array) else np
    return xp.stack([xp.ones_like(q2), xp.cos(q2), xp.sin(q2), xp.cos(2 * q2), xp.sin(2 * q2)], axis=-1)


class FastGeometry:
    """Geometry from the committed fits in ``assets/fast_fit.npz`` (see ``python -m jaxarm.arm.fit``).

    The polynomial's two partial derivatives are polynomials on the same monomials, so lengths and moment arms
    come from one (K,) x (K, 3M) product; the monomials come from a table of powers, not from ``pow``.

    The authors' muscle paths are additively separable: no path point of a muscle moves with both joints at once,
    so every length is a function of the shoulder angle plus one of the elbow angle, and the fitted coefficients
    of the mixed monomials x0^i x1^j (i, j >= 1) are at rounding level (< 1e-13 m). When all of them are below
    ``SEPARABLE_TOL_M`` only the 2D + 1 pure powers are used: the same polynomial (minus those rounding-level
    terms), a 19-row instead of a 55-row product at degree 9, and no gather.
    """

    #: Largest mixed-monomial coefficient (m) that is treated as zero (the fit's own error is ~1e-4 m).
    SEPARABLE_TOL_M = 1e-9

    def __init__(self, path: Path | str = FIT_PATH, mjcf: Path | str = MJCF_PATH):
        fit = np.load(path)
        if str(fit["mjcf_sha256"]) != file_sha256(mjcf):
            raise ValueError(f"{path} was fitted to a different {Path(mjcf).name}; "
                             "regenerate it with `python -m jaxarm.arm.fit`")
        self.names = tuple(str(n) for n in fit["names"])
        exps = np.asarray(fit["exponents"])
        coef = np.asarray(fit["length_coef"], float)           # (K, M) in normalised angles
        halfwidth = np.asarray(fit["q_halfwidth"], float)
        row = {tuple(e): k for k, e in enumerate(exps)}
        d_coef = [np.zeros_like(coef), np.zeros_like(coef)]     # d/dq_j re-expressed on the same monomials
        for k, (i, j) in enumerate(exps):
            if i > 0:
                d_coef[0][row[(i - 1, j)]] += i * coef[k] / halfwidth[0]
            if j > 0:
                d_coef[1][row[(i, j - 1)]] += j * coef[k] / halfwidth[1]
        self.n_muscles = coef.shape[1]
        self.exponents = jnp.asarray(exps)
        self.degree = int(exps.max())
        packed = np.concatenate([coef, d_coef[0], d_coef[1]], axis=1)   # (K, 3M): lengths, d/dq1, d/dq2
        mixed = (exps[:, 0] > 0) & (exps[:, 1] > 0)
        self.separable = bool(np.abs(coef[mixed]).max(initial=0.0) < self.SEPARABLE_TOL_M)
        if self.separable:
            # Rows in the order of the features: x0^0..x0^D, then x1^1..x1^D.
            pure = [row[(i, 0)] for i in range(self.degree + 1)] + [row[(0, j)] for j in range(1, self.degree + 1)]
            packed = packed[pure]
        self.all_coef = jnp.asarray(packed, jnp.float32)
        self.q_center = jnp.asarray(fit["q_center"], jnp.float32)
        self.q_halfwidth = jnp.asarray(halfwidth, jnp.float32)
        self.mass_coef = jnp.asarray(fit["mass_coef"], jnp.float32)       # (5, 3): M11, M12, M22

    def _monomials(self, q):
        """The monomials of the normalised angles, as a list of K arrays of q's batch shape (the rows of
        ``all_coef``, in order): :func:`ordered_dot` takes them one by one, so XLA fuses each power into the
        products that use it (stacked into one array, the powers, their concatenation and its slices were a dozen
        separate XLA:CPU thunks per arm step; a thunk's dispatch costs more than these few flops)."""
        # The barrier keeps x whole: for a batch of one, XLA's simplifier would otherwise fold the scale into each
        # power's constant (x^k = (q - c)^k (1/h)^k), other bits than in a batch of several.
        x = jax.lax.optimization_barrier((jnp.asarray(q, float) - self.q_center) / self.q_halfwidth)
        # x^k = x^(k-1) x, one product after the other (a cumprod may be computed as a scan tree)
        rows = [jnp.ones_like(x)]
        for _ in range(self.degree):
            rows.append(rows[-1] * x)
        if self.separable:
            return [r[..., 0] for r in rows] + [r[..., 1] for r in rows[1:]]
        return [rows[i][..., 0] * rows[j][..., 1] for i, j in np.asarray(self.exponents)]

    def mass_matrix(self, q2):
        c, s = jnp.cos(q2), jnp.sin(q2)
        m11, m12, m22 = ordered_dot(jnp.stack([jnp.ones_like(c), c, s, c * c - s * s, 2 * s * c]), self.mass_coef)
        return jnp.array([[m11, m12], [m12, m22]])

    def __call__(self, q, qd) -> ArmGeometry:
        # JAX's default float type: float32, or float64 when x64 is on (for finite-difference checks).
        q = jnp.asarray(q, float)
        qd = jnp.asarray(qd, float)
        m = self.n_muscles
        values = ordered_dot(self._monomials(q), self.all_coef)   # ordered: the same bits in any batch
        lengths, moment_arms = values[:m], -jnp.stack([values[m:2 * m], values[2 * m:]], axis=-1)
        mass, dmass = jax.jvp(self.mass_matrix, (q[1],), (jnp.ones((), q.dtype),))
        # Lagrange: M qdd + dM/dt qd - 1/2 d(qd^T M qd)/dq = tau, and M depends on the elbow angle only.
        dmass_qd = ordered_dot(dmass, qd)
        bias = dmass_qd * qd[1] - 0.5 * jnp.array([0.0, ordered_dot(qd, dmass_qd)])
        return ArmGeometry(lengths, moment_arms, mass, bias)
