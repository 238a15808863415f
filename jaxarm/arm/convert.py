"""Translate the authors' OpenSim arm (.osim) into the project's MJCF model and muscle table.

    python -m jaxarm.arm.convert [--osim PATH] [--out-dir jaxarm/arm/assets]

writes ``arm.xml`` (MJCF: bodies, inertias, the two hinges, one spatial tendon and one motor per muscle) and
``muscles.json`` (every Schutte 1993 muscle parameter as stored). Both outputs are deterministic: running the
command again on the same .osim reproduces them byte for byte.

Translation rules (each one measured by ``experiments/arm_geometry_error.py``):

* Bodies keep their osim names, masses, centres of mass and inertias; welded bodies (thorax, clavicle, scapula
  fixed to the world; radius and hand fixed to the ulna) become MJCF bodies without joints. Each CustomJoint
  becomes a hinge named like the osim joint (``shoulder``, ``elbow``) through the joint frame's origin about the
  osim axis, so qpos = the osim coordinate (arm_flex, elbow_flex) in rad with the same sign and zero.
* No gravity, contacts and constraints disabled (the authors' joint-limit forces are applied by the caller as
  joint torques), joints unlimited, timestep 1 ms.
* Each muscle is a spatial tendon named like the muscle through sites at its path points. OpenSim's
  ConditionalPathPoints (part of the path only while a coordinate is inside a range) have no MJCF equivalent;
  each muscle with such points gets a fixed set of them chosen by :func:`resolve_path` (see there).
* Each tendon is driven by a ``<motor>`` named like the muscle with **gear = -1**, so that a *positive* control
  equal to the muscle's tension in N *pulls* (shortens) the tendon: MuJoCo's actuator force on a tendon acts along
  +dL/dq (a positive force lengthens), and the generalized force is qfrc = gear · ctrl · ten_J = tension ·
  moment_arm with moment_arm = -ten_J = -dL/dq (positive: tension drives the joint towards +q, i.e. flexion).
"""
from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Optional

import numpy as np

from jaxarm.arm import osim
from jaxarm.config.arm import ELBOW_RANGE_DEG, SHOULDER_RANGE_DEG

ASSETS_DIR = Path(__file__).parent / "assets"
#: MJCF joint names for the osim coordinates, in qpos order.
JOINT_OF_COORDINATE = {"arm_flex": "shoulder", "elbow_flex": "elbow"}
#: The joint ranges over which the translation is judged, rad (the authors' task limits, [model:
#: task](../model.md#task-and-success), [the musculoskeletal arm](../model.md#the-musculoskeletal-arm)).
JOINT_RANGES_RAD = {
    "arm_flex": tuple(math.radians(v) for v in SHOULDER_RANGE_DEG),
    "elbow_flex": tuple(math.radians(v) for v in ELBOW_RANGE_DEG),
}
#: Grid on which conditional-point replacements are fitted (10-degree steps over both ranges: 13 x 15 postures);
#: the error is then measured on a finer grid by experiments/arm_geometry_error.py.
SELECTION_GRID_STEP_DEG = 10.0
MOTOR_GEAR = -1.0


# ----------------------------------------------------------------------------------------------- geometry helpers


def joint_range_grid(step_deg: float = SELECTION_GRID_STEP_DEG) -> list[dict[str, float]]:
    """Coordinate dicts over the joint ranges (shoulder outer, elbow inner), endpoints included."""
    axes = []
    for name in ("arm_flex", "elbow_flex"):
        lo, hi = JOINT_RANGES_RAD[name]
        n = int(round(math.degrees(hi - lo) / step_deg)) + 1
        axes.append(np.linspace(lo, hi, n))
    return [{"arm_flex": float(s), "elbow_flex": float(e)} for s in axes[0] for e in axes[1]]


class GridPoses:
    """Body poses over a grid of postures, and at +-h in each coordinate (for moment arms by central differences).

    Poses are stacked as (K, G, ...) with K = 1 + 2 x n_coordinates: the grid itself, then +h and -h for each
    coordinate in turn.
    """

    def __init__(self, model: osim.OsimModel, grid: list[dict[str, float]], h: float = 1e-6):
        self.grid, self.h = grid, h
        self.coordinates = tuple(c.name for c in model.coordinates)
        shifted = [grid]
        for c in self.coordinates:
            for sign in (+1, -1):
                shifted.append([{**g, c: g[c] + sign * h} for g in grid])
        ps = [[osim.body_transforms(model, g) for g in gs] for gs in shifted]
        self.rot = {b: np.array([[p[b][:3, :3] for p in row] for row in ps]) for b in ps[0][0]}
        self.pos = {b: np.array([[p[b][:3, 3] for p in row] for row in ps]) for b in ps[0][0]}
        self._fixed: dict = {}

    def point(self, body: str, location) -> np.ndarray:
        """(K, G, 3) ground positions of one body-fixed point."""
        return np.einsum("kgij,j->kgi", self.rot[body], np.asarray(location, dtype=float)) + self.pos[body]

    def fixed_point(self, body: str, location) -> np.ndarray:
        """:meth:`point`, memoised (for points that do not move during a fit)."""
        key = (body, tuple(float(v) for v in location))
        if key not in self._fixed:
            self._fixed[key] = self.point(body, location)
        return self._fixed[key]

    def length_and_moment_arms(self, points: np.ndarray, mask: Optional[np.ndarray] = None):
        """Lengths (G,) and moment arms -dL/dq (G, n_coordinates) of polylines through ``points`` (K, G, N, 3).

        With ``mask`` (G, N), only the points with mask[g, i] true are part of the path at posture g (the active
        set is frozen across the +-h evaluations, as OpenSim's moment arm is).
        """
        if mask is None:
            total = np.linalg.norm(np.diff(points, axis=2), axis=3).sum(axis=2)
        else:
            total = np.zeros(points.shape[:2])
            for pattern in np.unique(mask, axis=0):   # postures sharing an active set, in one go
                rows = np.all(mask == pattern, axis=1)
                sub = points[:, rows][:, :, pattern]
                total[:, rows] = np.linalg.norm(np.diff(sub, axis=2), axis=3).sum(axis=2)
        L = total[0]
        ma = [-(total[1 + 2 * j] - total[2 + 2 * j]) / (2 * self.h) for j in range(len(self.coordinates))]
        return L, np.stack(ma, axis=1)

    def path_geometry(self, bodies, locations, mask=None):
        """Lengths and moment arms of a path through body-fixed points (fixed locations, memoised)."""
        pts = np.stack([self.fixed_point(b, loc) for b, loc in zip(bodies, locations)], axis=2)
        return self.length_and_moment_arms(pts, mask)


def true_path_geometry(muscle: osim.Muscle, gp: GridPoses) -> tuple[np.ndarray, np.ndarray]:
    """The true OpenSim path on the grid: lengths (G,) and moment arms (G, 2), active set frozen at each posture."""
    mask = np.array([[p.active(g) for p in muscle.path] for g in gp.grid])
    return gp.path_geometry([p.body for p in muscle.path], [p.location for p in muscle.path], mask)


@dataclass(frozen=True)
class PathChoice:
    """The fixed path points used in the MJCF for one muscle, and how they were chosen."""

    points: tuple[osim.PathPoint, ...]
    notes: tuple[str, ...]   # one line per conditional point: what became of it
    length_rms_m: float      # RMS length error vs the true path on the selection grid
    moment_arm_rms_m: float  # RMS moment-arm error (both joints) vs the true path on the selection grid


def _describe(p: osim.PathPoint, index: int) -> str:
    lo, hi = (math.degrees(v) for v in p.range)
    return f"#{index} ({p.body}, active for {p.coordinate} in [{lo:.1f}, {hi:.1f}] deg)"


#: Weight of moment-arm residuals (m) relative to length residuals (m) in the replacement fit.
MOMENT_ARM_WEIGHT = 1.0
#: Weight of the penalty on moment arms whose sign differs from the true path's (m of wrong-signed moment arm).
SIGN_WEIGHT = 10.0
#: A fitted site stays within this distance (m, per axis) of the conditional point it replaces.
FIT_BOX_M = 0.03
#: Pull of a fitted site towards the conditional point it replaces: moving a site by 10 mm costs as much as
#: 0.1 mm more RMS length error over the grid (residual weight = FIT_PRIOR_WEIGHT * sqrt(grid size)).
FIT_PRIOR_WEIGHT = 0.01
#: Fitted site coordinates live on a lattice of this step (m) so regeneration is byte-for-byte stable.
FIT_ROUND_M = 1e-5


def _lattice_polish(cost, x: np.ndarray, step: float = None, max_sweeps: int = 500) -> np.ndarray:
    """Round ``x`` to the FIT_ROUND_M lattice, then descend coordinate-wise on the lattice to a local minimum.

    Why: the optimum of a flat least-squares problem is only determined to a few micrometres, so rounding the
    optimiser's answer could land on either side of a rounding boundary on another machine. A lattice local
    minimum reached by comparisons is reproducible wherever the costs of neighbouring lattice points compare the
    same way.
    """
    step = FIT_ROUND_M if step is None else step
    k = np.round(np.asarray(x) / step).astype(np.int64)
    best = cost(k * step)
    for _ in range(max_sweeps):
        improved = False
        for j in range(k.size):
            for d in (-1, 1):
                trial = k.copy()
                trial[j] += d
                c = cost(trial * step)
                if c < best:
                    k, best, improved = trial, c, True
        if not improved:
            break
    return k * step


def resolve_path(model: osim.OsimModel, muscle: osim.Muscle, gp: Optional[GridPoses] = None) -> PathChoice:
    """Replace a muscle's ConditionalPathPoints by fixed sites.

    A conditional point active over the whole joint range is kept as an ordinary point and one never active is
    dropped. For the others ("switching" points, a discrete stand-in for wrapping), every subset of them is
    tried as fixed sites whose locations (on the same body, within +-FIT_BOX_M of the stored location) are fitted
    by least squares to the true switching path's muscle-tendon lengths and moment arms over the joint-range grid
    then polished on a 10-micrometre lattice (:func:`_lattice_polish`)
    (residuals: length error, MOMENT_ARM_WEIGHT x moment-arm error, SIGN_WEIGHT x any moment arm of the wrong
    sign (so a fitted path never turns a flexor into an extensor where the true path is not),
    FIT_PRIOR_WEIGHT sqrt(G) x displacement). The subset
    with the smallest RMS residual wins; the empty subset (drop them all) is one of the candidates.
    """
    from scipy.optimize import least_squares  # a dependency of jax

    cond = [i for i, p in enumerate(muscle.path) if p.conditional]
    gp = GridPoses(model, joint_range_grid()) if gp is None else gp
    if not cond:
        return PathChoice(muscle.path, (), 0.0, 0.0)
    active = np.array([[muscle.path[i].active(g) for i in cond] for g in gp.grid])
    always = {i for i, col in zip(cond, active.T) if col.all()}
    never = {i for i, col in zip(cond, active.T) if not col.any()}
    switching = [i for i in cond if i not in always | never]
    L_true, ma_true = true_path_geometry(muscle, gp)
    prior = FIT_PRIOR_WEIGHT * math.sqrt(len(gp.grid))

    def candidate(kept: tuple[int, ...], locs: np.ndarray):
        idx = [i for i in range(len(muscle.path)) if i not in cond or i in always or i in kept]
        locations = np.array([locs[kept.index(i)] if i in kept else muscle.path[i].location for i in idx])
        return idx, locations

    def residuals(x: np.ndarray, kept: tuple[int, ...]) -> np.ndarray:
        locs = x.reshape(-1, 3)
        idx, _ = candidate(kept, locs)
        pts = np.stack([gp.point(muscle.path[i].body, locs[kept.index(i)]) if i in kept
                        else gp.fixed_point(muscle.path[i].body, muscle.path[i].location) for i in idx], axis=2)
        L, ma = gp.length_and_moment_arms(pts)
        x0 = np.array([muscle.path[i].location for i in kept]).ravel() if kept else np.zeros(0)
        wrong_sign = np.maximum(0.0, -ma * np.sign(ma_true)).ravel()
        return np.concatenate([L - L_true, MOMENT_ARM_WEIGHT * (ma - ma_true).ravel(), SIGN_WEIGHT * wrong_sign,
                               prior * (x - x0)])

    best = None
    for r in range(len(switching) + 1):
        for kept in itertools.combinations(switching, r):
            x0 = np.array([muscle.path[i].location for i in kept], dtype=float).ravel()
            if kept:
                fit = least_squares(residuals, x0, args=(kept,), bounds=(x0 - FIT_BOX_M, x0 + FIT_BOX_M),
                                    x_scale=0.01, xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=2000)
                x = _lattice_polish(lambda z: float(np.sum(residuals(z, kept) ** 2)), fit.x)
            else:
                x = x0
            cost = float(np.sum(residuals(x, kept) ** 2))
            if best is None or cost < best[0] * (1 - 1e-9):
                best = (cost, kept, x.reshape(-1, 3))
    _, kept, locs = best
    idx, locations = candidate(kept, locs)
    points = []
    for i, loc in zip(idx, locations):
        p = muscle.path[i]
        points.append(osim.PathPoint(p.name, p.body, tuple(float(v) for v in loc)))
    notes = []
    for i in cond:
        p = muscle.path[i]
        if i in always:
            notes.append(f"{_describe(p, i)}: always active in range, kept as is")
        elif i in never:
            notes.append(f"{_describe(p, i)}: never active in range, dropped")
        elif i in kept:
            shift = np.asarray(locs[kept.index(i)]) - np.asarray(p.location)
            notes.append(f"{_describe(p, i)}: replaced by a fitted fixed site moved by "
                         f"({_vec(np.round(shift * 1e3, 2))}) mm")
        else:
            notes.append(f"{_describe(p, i)}: dropped (fit)")
    L, ma = gp.path_geometry([muscle.path[i].body for i in idx], locations)
    return PathChoice(tuple(points), tuple(notes), float(np.sqrt(np.mean((L - L_true) ** 2))),
                      float(np.sqrt(np.mean((ma - ma_true) ** 2))))


# ----------------------------------------------------------------------------------------------- MJCF writing


def _fmt(v: float) -> str:
    s = f"{float(v):.9g}"
    return "0" if s in ("-0", "0") else s


def _vec(v) -> str:
    return " ".join(_fmt(x) for x in v)


def _quat(R: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix."""
    m = R
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    q = np.asarray(q) / np.linalg.norm(q)
    return tuple(q if q[0] >= 0 else -q)


def _hinge_of(body: osim.Body) -> Optional[tuple[str, np.ndarray, np.ndarray]]:
    """(coordinate, position in body frame, unit axis in body frame) of a CustomJoint that is a pure hinge."""
    if body.joint_type != "CustomJoint":
        return None
    driven = [ta for ta in body.transform_axes if ta.function == "linear"]
    if len(driven) != 1 or not driven[0].name.startswith("rotation") or tuple(driven[0].coefficients) != (1.0, 0.0):
        raise ValueError(f"joint {body.joint_name!r}: only a single rotation equal to its coordinate is supported")
    for ta in body.transform_axes:
        if ta.function == "constant" and ta.coefficients[0] != 0.0:
            raise ValueError(f"joint {body.joint_name!r}: constant {ta.name} = {ta.coefficients[0]} is not supported")
    R_BM = osim.rotation_xyz_body_fixed(body.orientation)
    axis = R_BM @ (np.asarray(driven[0].axis) / np.linalg.norm(driven[0].axis))
    return driven[0].coordinate, np.asarray(body.location, dtype=float), axis


def _site_name(muscle: str, k: int) -> str:
    return f"{muscle}_p{k}"


def build_mjcf(model: osim.OsimModel, paths: dict[str, PathChoice], source_sha256: str) -> str:
    """The MJCF text for the parsed model and the chosen fixed paths."""
    zero = {c.name: 0.0 for c in model.coordinates}
    children: dict[Optional[str], list[osim.Body]] = {}
    for b in model.bodies:
        children.setdefault(b.parent, []).append(b)
    sites: dict[str, list[str]] = {}
    for mus in model.muscles:
        for k, p in enumerate(paths[mus.name].points):
            sites.setdefault(p.body, []).append(
                f'<site name="{_site_name(mus.name, k)}" pos="{_vec(p.location)}" size="0.002"/>')

    lines = [
        f'<mujoco model="{model.name}">',
        f"  <!-- Generated by `python -m jaxarm.arm.convert` from {Path(model.source).name}",
        f"       (sha256 {source_sha256}). Do not edit: regenerate.",
        "       Units SI. qpos = (shoulder, elbow) = osim (arm_flex, elbow_flex), rad, same zero and sign.",
        "       Motors: gear -1, so ctrl = muscle tension in N (>= 0) pulls the tendon;",
        "       qfrc_actuator = tension * moment_arm, moment_arm = -dL/dq = -ten_J. -->",
        '  <compiler angle="radian"/>',
        '  <option timestep="0.001" gravity="0 0 0">',
        '    <flag contact="disable" constraint="disable"/>',
        "  </option>",
        "  <worldbody>",
    ]

    def emit(body: osim.Body, depth: int) -> None:
        ind = "  " * depth
        X = osim.body_in_parent(body, zero)
        attrs = f'name="{body.name}" pos="{_vec(X[:3, 3])}"'
        q = _quat(X[:3, :3])
        if not np.allclose(q, (1.0, 0.0, 0.0, 0.0), atol=0.0, rtol=0.0):
            attrs += f' quat="{_vec(q)}"'
        lines.append(f"{ind}<body {attrs}>")
        if body.mass > 0:
            lines.append(f'{ind}  <inertial pos="{_vec(body.mass_center)}" mass="{_fmt(body.mass)}" '
                         f'fullinertia="{_vec(body.inertia)}"/>')
        hinge = _hinge_of(body)
        if hinge is not None:
            coord, pos, axis = hinge
            lines.append(f'{ind}  <joint name="{JOINT_OF_COORDINATE[coord]}" type="hinge" pos="{_vec(pos)}" '
                         f'axis="{_vec(axis)}" limited="false"/>')
        for s in sites.get(body.name, []):
            lines.append(f"{ind}  {s}")
        for child in children.get(body.name, []):
            emit(child, depth + 1)
        lines.append(f"{ind}</body>")

    ground = [b for b in model.bodies if b.parent is None]
    if len(ground) != 1:
        raise ValueError("expected exactly one root body (ground)")
    for s in sites.get(ground[0].name, []):
        lines.append(f"    {s}")
    for child in children.get(ground[0].name, []):
        emit(child, 2)
    lines.append("  </worldbody>")

    lines.append("  <tendon>")
    for mus in model.muscles:
        ch = paths[mus.name]
        if ch.notes:
            lines.append(f"    <!-- {mus.name}: conditional path points (osim path index):")
            lines += [f"         {n}" for n in ch.notes]
            lines.append(f"         fixed path vs true path over the joint ranges: length RMS "
                         f"{ch.length_rms_m * 1e3:.2f} mm, moment-arm RMS {ch.moment_arm_rms_m * 1e3:.2f} mm -->")
        lines.append(f'    <spatial name="{mus.name}" width="0.001">')
        for k in range(len(ch.points)):
            lines.append(f'      <site site="{_site_name(mus.name, k)}"/>')
        lines.append("    </spatial>")
    lines.append("  </tendon>")

    lines.append("  <actuator>")
    for mus in model.muscles:
        lines.append(f'    <motor name="{mus.name}" tendon="{mus.name}" gear="{_fmt(MOTOR_GEAR)}" ctrllimited="false"/>')
    lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------- muscle table

_JSON_KEYS = {
    "max_isometric_force": "max_isometric_force_n",
    "optimal_fiber_length": "optimal_fiber_length_m",
    "tendon_slack_length": "tendon_slack_length_m",
    "pennation_angle": "pennation_angle_rad",
    "max_contraction_velocity": "max_contraction_velocity",
    "damping": "damping",
    "time_scale": "time_scale_s",
    "activation1": "activation1",
    "activation2": "activation2",
    "tendon_force_length_curve": "tendon_force_length",
    "active_force_length_curve": "active_force_length",
    "passive_force_length_curve": "passive_force_length",
}


def build_muscle_table(model: osim.OsimModel, source_sha256: str) -> dict:
    """``{"source": ..., "muscles": [...]}``: every muscle in osim order with its parameters as stored."""
    muscles = []
    for m in model.muscles:
        entry: dict = {"name": m.name}
        for tag, key in _JSON_KEYS.items():
            v = getattr(m, tag)
            entry[key] = {"x": list(v.x), "y": list(v.y)} if isinstance(v, osim.Spline) else float(v)
        entry["from_defaults"] = [_JSON_KEYS[t] for t in m.defaulted]
        muscles.append(entry)
    return {
        "source": Path(model.source).name,
        "source_sha256": source_sha256,
        "generated_by": "python -m jaxarm.arm.convert",
        "notes": ("Values as stored in the .osim. A muscle that omits a field takes the value of the file's "
                  "<defaults> Schutte1993Muscle (listed in from_defaults). max_contraction_velocity is in optimal "
                  "fibre lengths per second; 0 means the file stores 0 (no value)."),
        "muscles": muscles,
    }


# ----------------------------------------------------------------------------------------------- audit


def dense_tendon_jacobian(mjmodel, mjdata) -> np.ndarray:
    """(ntendon, nv) dL/dq from MuJoCo's C data (MuJoCo 4 stores ``ten_J`` sparse, rows per ``ten_J_rowadr``)."""
    J = np.asarray(mjdata.ten_J)
    if J.size == mjmodel.ntendon * mjmodel.nv and not hasattr(mjmodel, "ten_J_rowadr"):
        return J.reshape(mjmodel.ntendon, mjmodel.nv).copy()
    out = np.zeros((mjmodel.ntendon, mjmodel.nv))
    for t in range(mjmodel.ntendon):
        a, n = mjmodel.ten_J_rowadr[t], mjmodel.ten_J_rownnz[t]
        out[t, mjmodel.ten_J_colind[a:a + n]] = J.ravel()[a:a + n]
    return out


def mjcf_path_geometry(mjmodel, grid: list[dict[str, float]]) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo C tendon lengths (G, M) and moment arms -ten_J (G, M, 2) on a grid of osim coordinate dicts."""
    import mujoco

    d = mujoco.MjData(mjmodel)
    L, ma = [], []
    for g in grid:
        d.qpos[:] = (g["arm_flex"], g["elbow_flex"])
        mujoco.mj_kinematics(mjmodel, d)
        mujoco.mj_comPos(mjmodel, d)
        mujoco.mj_tendon(mjmodel, d)
        L.append(d.ten_length.copy())
        ma.append(-dense_tendon_jacobian(mjmodel, d))
    return np.asarray(L), np.asarray(ma)


# ----------------------------------------------------------------------------------------------- entry point


def convert(osim_path: Optional[str | Path] = None) -> tuple[str, str]:
    """(arm.xml text, muscles.json text) for the given .osim (default: the authors' arm under ``../shared``)."""
    path = Path(osim_path) if osim_path is not None else osim.default_osim_path()
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    model = osim.parse_osim(path)
    # The MJCF's qpos order, the joint names and the fitting grid are those of a shoulder-elbow arm.
    expected = tuple(JOINT_OF_COORDINATE)
    if model.coordinate_names != expected:
        raise ValueError(f"{path}: coordinates {model.coordinate_names}; the converter translates a two-hinge arm "
                         f"with coordinates {expected} in that order")
    gp = GridPoses(model, joint_range_grid())
    paths = {m.name: resolve_path(model, m, gp) for m in model.muscles}
    xml = build_mjcf(model, paths, sha)
    table = json.dumps(build_muscle_table(model, sha), indent=1) + "\n"
    return xml, table


def main(argv: Optional[list[str]] = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m jaxarm.arm.convert", description=__doc__.split("\n\n")[0])
    ap.add_argument("--osim", type=Path, default=None,
                    help="source .osim (default: ../shared/spec/arm/SUNY_arm_2DOFs_horizon.osim from the repo root)")
    ap.add_argument("--out-dir", type=Path, default=ASSETS_DIR, help="where to write arm.xml and muscles.json")
    args = ap.parse_args(argv)
    xml, table = convert(args.osim)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    (args.out_dir / "arm.xml").write_text(xml)
    (args.out_dir / "muscles.json").write_text(table)
    print(f"wrote {args.out_dir / 'arm.xml'} and {args.out_dir / 'muscles.json'}")


if __name__ == "__main__":
    main()
