"""The authors' OpenSim arm (``SUNY_arm_2DOFs_horizon.osim``): parse it and evaluate its true muscle paths.

Parsing uses only ``xml.etree``; the result is plain frozen dataclasses (SI units: m, kg, kg m², rad, N, s).
The geometry evaluator (numpy) reproduces OpenSim's kinematics of this file, including ConditionalPathPoints
(a conditional point is part of the path only while its coordinate lies inside its range, bounds inclusive), so the
MJCF translation in :mod:`jaxarm.arm.convert` can be audited against it.

OpenSim conventions used (OpenSim 2.x/3.x model format, which this file is):
- A body's joint places the joint frame F in the parent at ``location_in_parent`` / ``orientation_in_parent`` and the
  joint frame M in the child at ``location`` / ``orientation``; X_parent_child(q) = X_PF · X_FM(q) · X_BM⁻¹.
- Orientations are body-fixed X-Y-Z Euler angles (R = Rx(a) Ry(b) Rz(c)).
- A CustomJoint's SpatialTransform applies rotation1, rotation2, rotation3 in sequence (each about its axis, a
  body-fixed sequence), then translations along the three translation axes in F. In this model only one rotation of
  each joint depends on a coordinate (with f(q) = q), so the sequence convention does not change any result.
- Muscle-tendon length = sum of distances between consecutive active path points (no wrap objects in this file).
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

#: Default location of the source model, relative to the repository root (``/work/shared`` is ``../shared``).
DEFAULT_OSIM_RELPATH = Path("..") / "shared" / "spec" / "arm" / "SUNY_arm_2DOFs_horizon.osim"

#: Muscle parameters read as scalars (osim tag names); a muscle that omits one takes the ``<defaults>`` value.
MUSCLE_SCALARS = (
    "max_isometric_force",
    "optimal_fiber_length",
    "tendon_slack_length",
    "pennation_angle",
    "max_contraction_velocity",
    "damping",
    "time_scale",
    "activation1",
    "activation2",
)
#: Muscle curves (osim tag names), each a NaturalCubicSpline with x/y knots.
MUSCLE_CURVES = ("tendon_force_length_curve", "active_force_length_curve", "passive_force_length_curve")


def repo_root() -> Path:
    """The repository root (the directory holding the ``jaxarm`` package)."""
    return Path(__file__).resolve().parents[2]


def default_osim_path() -> Path:
    """``../shared/spec/arm/SUNY_arm_2DOFs_horizon.osim`` relative to the repository root (may not exist)."""
    return (repo_root() / DEFAULT_OSIM_RELPATH).resolve()


# ----------------------------------------------------------------------------------------------- dataclasses


@dataclass(frozen=True)
class Spline:
    """Knots of an OpenSim NaturalCubicSpline, as stored."""

    x: tuple[float, ...]
    y: tuple[float, ...]


@dataclass(frozen=True)
class TransformAxis:
    """One of a CustomJoint's six transform axes: motion = f(coordinate) about/along ``axis`` (in frame F)."""

    name: str                   # rotation1..3, translation1..3
    axis: tuple[float, float, float]
    coordinate: Optional[str]   # None when the function is a constant
    function: str               # "linear" or "constant"
    coefficients: tuple[float, ...]  # linear: (slope, intercept); constant: (value,)

    def value(self, coords: dict[str, float]) -> float:
        """The rotation angle (rad) or translation (m) at the given coordinate values."""
        if self.function == "constant":
            return self.coefficients[0]
        return self.coefficients[0] * coords[self.coordinate] + self.coefficients[1]


@dataclass(frozen=True)
class Coordinate:
    """A generalized coordinate of a joint (rad for rotational coordinates)."""

    name: str
    joint: str
    motion_type: str
    default_value: float
    initial_value: Optional[float]
    range: tuple[float, float]
    clamped: bool


@dataclass(frozen=True)
class Body:
    """A body with its inertial properties and the joint that connects it to its parent.

    ``inertia`` is (xx, yy, zz, xy, xz, yz) about the centre of mass in the body frame, kg m².
    """

    name: str
    mass: float
    mass_center: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]
    parent: Optional[str] = None            # None for ground
    joint_name: Optional[str] = None
    joint_type: Optional[str] = None        # "WeldJoint" or "CustomJoint"
    location_in_parent: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation_in_parent: tuple[float, float, float] = (0.0, 0.0, 0.0)
    location: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    transform_axes: tuple[TransformAxis, ...] = ()   # CustomJoint only
    coordinates: tuple[str, ...] = ()


@dataclass(frozen=True)
class PathPoint:
    """A muscle path point fixed in ``body`` at ``location`` (m).

    Conditional points (``coordinate`` not None) are part of the path only while ``range[0] <= q <= range[1]``.
    """

    name: str
    body: str
    location: tuple[float, float, float]
    coordinate: Optional[str] = None
    range: Optional[tuple[float, float]] = None

    @property
    def conditional(self) -> bool:
        return self.coordinate is not None

    def active(self, coords: dict[str, float]) -> bool:
        if self.coordinate is None:
            return True
        q = coords[self.coordinate]
        return self.range[0] <= q <= self.range[1]


@dataclass(frozen=True)
class Muscle:
    """A Schutte1993Muscle with every parameter as stored (or from ``<defaults>`` where omitted).

    Units: max_isometric_force N; optimal_fiber_length, tendon_slack_length m; pennation_angle rad;
    max_contraction_velocity optimal fibre lengths per second; time_scale s; activation1/2, damping dimensionless.
    ``defaulted`` lists the fields (osim tag names) that came from the ``<defaults>`` muscle.
    """

    name: str
    kind: str
    max_isometric_force: float
    optimal_fiber_length: float
    tendon_slack_length: float
    pennation_angle: float
    max_contraction_velocity: float
    damping: float
    time_scale: float
    activation1: float
    activation2: float
    tendon_force_length_curve: Spline
    active_force_length_curve: Spline
    passive_force_length_curve: Spline
    path: tuple[PathPoint, ...]
    defaulted: tuple[str, ...] = ()


@dataclass(frozen=True)
class OsimModel:
    """The parsed model: bodies in file order (ground first), coordinates, muscles in file order."""

    name: str
    gravity: tuple[float, float, float]
    bodies: tuple[Body, ...]
    coordinates: tuple[Coordinate, ...]
    muscles: tuple[Muscle, ...]
    source: str = ""

    def body(self, name: str) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(f"no body named {name!r}")

    def coordinate(self, name: str) -> Coordinate:
        for c in self.coordinates:
            if c.name == name:
                return c
        raise KeyError(f"no coordinate named {name!r}")

    def muscle(self, name: str) -> Muscle:
        for m in self.muscles:
            if m.name == name:
                return m
        raise KeyError(f"no muscle named {name!r}")

    @property
    def muscle_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.muscles)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.coordinates)


# ----------------------------------------------------------------------------------------------- parsing


class OsimFormatError(ValueError):
    """A .osim file this parser cannot read. The message is one line naming the file and the element at fault."""


def _where(el: ET.Element) -> str:
    """``<Tag name='x'>`` (or ``<Tag>``) for error messages."""
    name = el.get("name")
    return f"<{el.tag}>" if name is None else f"<{el.tag} name={name!r}>"


def _text(el: Optional[ET.Element]) -> Optional[str]:
    return None if el is None or el.text is None else el.text.strip()


def _floats(text: str, where: str) -> tuple[float, ...]:
    try:
        return tuple(float(t) for t in text.split())
    except ValueError:
        raise OsimFormatError(f"{where}: expected numbers, got {text!r}") from None


def _required_text(el: ET.Element, tag: str, where: str) -> str:
    t = _text(el.find(tag))
    if not t:
        raise OsimFormatError(f"{where} has no <{tag}>")
    return t


def _required_floats(el: ET.Element, tag: str, where: str, count: Optional[int] = None) -> tuple[float, ...]:
    """The numbers of a required child element; ``count``, when given, is how many it must hold."""
    t = _required_text(el, tag, where)
    v = _floats(t, f"{where} <{tag}>")
    if count is not None and len(v) != count:
        raise OsimFormatError(f"{where} <{tag}>: expected {count} number{'s' * (count != 1)}, got {t!r}")
    return v


def _vec3(el: ET.Element, tag: str, where: str, default=(0.0, 0.0, 0.0)) -> tuple[float, float, float]:
    """An optional 3-vector (absent or empty: ``default``)."""
    if not _text(el.find(tag)):
        return default
    return _required_floats(el, tag, where, 3)  # type: ignore[return-value]


def _scalar(el: ET.Element, tag: str, where: str) -> Optional[float]:
    """An optional number (None when absent or empty)."""
    if not _text(el.find(tag)):
        return None
    return _required_floats(el, tag, where, 1)[0]


def _spline(el: Optional[ET.Element], where: str) -> Optional[Spline]:
    if el is None:
        return None
    where = f"{where} <{el.tag}>"
    sp = el.find("NaturalCubicSpline")
    if sp is None:
        raise OsimFormatError(f"{where}: only NaturalCubicSpline curves are supported")
    x, y = _required_floats(sp, "x", where), _required_floats(sp, "y", where)
    if len(x) != len(y):
        raise OsimFormatError(f"{where}: {len(x)} x knots but {len(y)} y knots")
    return Spline(x, y)


def _parse_path(muscle_el: ET.Element, where: str) -> tuple[PathPoint, ...]:
    pps = muscle_el.find("GeometryPath/PathPointSet/objects")
    if pps is None:
        raise OsimFormatError(f"{where} has no GeometryPath/PathPointSet")
    points = []
    for k, p in enumerate(pps):
        # Point names need not be unique (the authors' file names several conditional points "default").
        at = f"{where} path point #{k} {_where(p)}"
        if p.tag == "PathPoint":
            points.append(PathPoint(p.get("name", ""), _required_text(p, "body", at), _vec3(p, "location", at)))
        elif p.tag == "ConditionalPathPoint":
            rng = _required_floats(p, "range", at, 2)
            points.append(PathPoint(p.get("name", ""), _required_text(p, "body", at), _vec3(p, "location", at),
                                    coordinate=_required_text(p, "coordinate", at), range=(rng[0], rng[1])))
        else:
            raise OsimFormatError(f"{where}: unsupported path point type <{p.tag}>")
    return tuple(points)


def _muscle_defaults(root: ET.Element, kind: str) -> dict:
    d = root.find(f"Model/defaults/{kind}")
    out: dict = {}
    if d is None:
        return out
    where = f"<defaults> {_where(d)}"
    for tag in MUSCLE_SCALARS:
        v = _scalar(d, tag, where)
        if v is not None:
            out[tag] = v
    for tag in MUSCLE_CURVES:
        s = _spline(d.find(tag), where)
        if s is not None:
            out[tag] = s
    return out


def _parse_muscle(el: ET.Element, defaults: dict) -> Muscle:
    name = el.get("name")
    where = f"muscle {name!r}"
    values, defaulted = {}, []
    for tag in MUSCLE_SCALARS:
        v = _scalar(el, tag, where)
        if v is None:
            if tag not in defaults:
                raise OsimFormatError(f"{where} omits <{tag}> and <defaults> has none")
            v, _ = defaults[tag], defaulted.append(tag)
        values[tag] = v
    for tag in MUSCLE_CURVES:
        s = _spline(el.find(tag), where)
        if s is None:
            if tag not in defaults:
                raise OsimFormatError(f"{where} omits <{tag}> and <defaults> has none")
            s, _ = defaults[tag], defaulted.append(tag)
        values[tag] = s
    return Muscle(name=name, kind=el.tag, path=_parse_path(el, where), defaulted=tuple(defaulted), **values)


def _parse_transform_axes(sp: ET.Element, joint: str) -> tuple[TransformAxis, ...]:
    axes = []
    for ta in sp.findall("TransformAxis"):
        where = f"joint {joint!r} {_where(ta)}"
        fn = ta.find("function")
        f = fn[0] if fn is not None and len(fn) else None
        coord = _text(ta.find("coordinates")) or None
        if f is None or f.tag == "Constant":
            value = _scalar(f, "value", where) if f is not None else 0.0
            axes.append(TransformAxis(ta.get("name"), _vec3(ta, "axis", where), None, "constant", (value or 0.0,)))
        elif f.tag == "LinearFunction":
            coefs = _required_floats(f, "coefficients", f"{where} <LinearFunction>", 2)
            if not coord or len(coord.split()) != 1:
                raise OsimFormatError(f"{where}: a LinearFunction needs exactly one coordinate")
            axes.append(TransformAxis(ta.get("name"), _vec3(ta, "axis", where), coord, "linear", coefs))
        else:
            raise OsimFormatError(f"{where}: unsupported function <{f.tag}>")
    return tuple(axes)


def parse_osim(path: Optional[str | Path] = None) -> OsimModel:
    """Parse an OpenSim 2.x/3.x model file (default: the authors' arm under ``../shared``).

    Raises :class:`OsimFormatError` (a ValueError), one line naming the file and the element, for a file that is
    not well-formed XML, lacks an element the model needs, holds a non-number where a number belongs, or refers to
    a body or coordinate it does not define.
    """
    path = Path(path) if path is not None else default_osim_path()
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise OsimFormatError(f"{path}: not well-formed XML ({e})") from None
    try:
        return _parse_model(root, path)
    except OsimFormatError as e:
        raise OsimFormatError(f"{path}: {e}") from None


def _parse_model(root: ET.Element, path: Path) -> OsimModel:
    model_el = root.find("Model")
    if model_el is None:
        raise OsimFormatError("no <Model> element")

    bodies, coordinates = [], []
    for b in model_el.findall("BodySet/objects/Body"):
        name = b.get("name")
        where = f"body {name!r}"
        common = dict(
            name=name, mass=_scalar(b, "mass", where) or 0.0, mass_center=_vec3(b, "mass_center", where),
            inertia=tuple(_scalar(b, f"inertia_{k}", where) or 0.0 for k in ("xx", "yy", "zz", "xy", "xz", "yz")),
        )
        joint_el = b.find("Joint")
        j = joint_el[0] if joint_el is not None and len(joint_el) else None
        if j is None:
            bodies.append(Body(**common))
            continue
        if j.tag not in ("WeldJoint", "CustomJoint"):
            raise OsimFormatError(f"{where}: unsupported joint type <{j.tag}>")
        jwhere = f"{where} joint {_where(j)}"
        coord_names = []
        for c in j.findall("CoordinateSet/objects/Coordinate"):
            cwhere = f"{jwhere} {_where(c)}"
            rng = _required_floats(c, "range", cwhere, 2)
            coordinates.append(Coordinate(
                name=c.get("name"), joint=j.get("name"), motion_type=_text(c.find("motion_type")),
                default_value=_scalar(c, "default_value", cwhere) or 0.0,
                initial_value=_scalar(c, "initial_value", cwhere), range=(rng[0], rng[1]),
                clamped=_text(c.find("clamped")) == "true"))
            coord_names.append(c.get("name"))
        sp = j.find("SpatialTransform")
        bodies.append(Body(
            **common, parent=_required_text(j, "parent_body", jwhere), joint_name=j.get("name"), joint_type=j.tag,
            location_in_parent=_vec3(j, "location_in_parent", jwhere),
            orientation_in_parent=_vec3(j, "orientation_in_parent", jwhere),
            location=_vec3(j, "location", jwhere), orientation=_vec3(j, "orientation", jwhere),
            transform_axes=_parse_transform_axes(sp, j.get("name")) if sp is not None else (),
            coordinates=tuple(coord_names)))

    muscles = []
    for m in model_el.findall("ForceSet/objects/*"):
        if not m.tag.endswith("Muscle"):
            continue
        muscles.append(_parse_muscle(m, _muscle_defaults(root, m.tag)))

    _check_references(bodies, coordinates, muscles)
    grav = _vec3(model_el, "gravity", "<Model>")
    return OsimModel(name=model_el.get("name"), gravity=grav, bodies=tuple(bodies), coordinates=tuple(coordinates),
                     muscles=tuple(muscles), source=str(path))


def _check_references(bodies: list[Body], coordinates: list[Coordinate], muscles: list[Muscle]) -> None:
    """Every body and coordinate a joint or path point names exists, and only one body (ground) has no joint.

    Why here: a dangling name would otherwise surface as a KeyError deep inside the kinematics.
    """
    body_names, coord_names = {b.name for b in bodies}, {c.name for c in coordinates}
    roots = [b.name for b in bodies if b.parent is None]
    if len(roots) != 1:
        raise OsimFormatError(f"expected exactly one body without a joint (ground), found {roots}")
    for b in bodies:
        if b.parent is not None and b.parent not in body_names:
            raise OsimFormatError(f"body {b.name!r} joint <{b.joint_type} name={b.joint_name!r}>: "
                                  f"parent_body {b.parent!r} is not a body of the model")
        for ta in b.transform_axes:
            if ta.coordinate is not None and ta.coordinate not in coord_names:
                raise OsimFormatError(f"joint {b.joint_name!r} <TransformAxis name={ta.name!r}>: "
                                      f"coordinate {ta.coordinate!r} is not a coordinate of the model")
    for m in muscles:
        for k, p in enumerate(m.path):
            if p.body not in body_names:
                raise OsimFormatError(f"muscle {m.name!r} path point #{k} {p.name!r}: "
                                      f"body {p.body!r} is not a body of the model")
            if p.coordinate is not None and p.coordinate not in coord_names:
                raise OsimFormatError(f"muscle {m.name!r} path point #{k} {p.name!r}: "
                                      f"coordinate {p.coordinate!r} is not a coordinate of the model")


# ----------------------------------------------------------------------------------------------- kinematics


def rotation_xyz_body_fixed(angles) -> np.ndarray:
    """R = Rx(a) · Ry(b) · Rz(c): OpenSim's body-fixed X-Y-Z orientation convention."""
    a, b, c = angles
    return _rot([1.0, 0.0, 0.0], a) @ _rot([0.0, 1.0, 0.0], b) @ _rot([0.0, 0.0, 1.0], c)


def _rot(axis, angle: float) -> np.ndarray:
    """Rotation matrix about a (normalised) axis by ``angle`` rad (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    k = k / np.linalg.norm(k)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


def _transform(R: np.ndarray, p) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def _inv(T: np.ndarray) -> np.ndarray:
    R, p = T[:3, :3], T[:3, 3]
    return _transform(R.T, -R.T @ p)


def joint_motion(body: Body, coords: dict[str, float]) -> np.ndarray:
    """X_FM(q): the joint's motion from frame F (in parent) to frame M (in child), 4x4."""
    R, p = np.eye(3), np.zeros(3)
    for ta in body.transform_axes:
        v = ta.value(coords)
        if ta.name.startswith("rotation"):
            R = R @ _rot(ta.axis, v)
        else:
            p = p + v * np.asarray(ta.axis, dtype=float) / np.linalg.norm(ta.axis)
    return _transform(R, p)


def body_in_parent(body: Body, coords: dict[str, float]) -> np.ndarray:
    """X_parent_body(q) = X_PF · X_FM(q) · X_BM⁻¹ (4x4)."""
    X_PF = _transform(rotation_xyz_body_fixed(body.orientation_in_parent), body.location_in_parent)
    X_BM = _transform(rotation_xyz_body_fixed(body.orientation), body.location)
    return X_PF @ joint_motion(body, coords) @ _inv(X_BM)


def body_transforms(model: OsimModel, coords: dict[str, float]) -> dict[str, np.ndarray]:
    """Pose of every body in ground (4x4) at the given coordinate values (rad)."""
    out: dict[str, np.ndarray] = {}
    pending = list(model.bodies)
    while pending:
        progressed = False
        for b in list(pending):
            if b.parent is None:
                out[b.name] = np.eye(4)
            elif b.parent in out:
                out[b.name] = out[b.parent] @ body_in_parent(b, coords)
            else:
                continue
            pending.remove(b)
            progressed = True
        if not progressed:
            raise ValueError(f"bodies with unknown parents: {[b.name for b in pending]}")
    return out


def path_points_in_ground(model: OsimModel, muscle: Muscle, coords: dict[str, float],
                          poses: Optional[dict[str, np.ndarray]] = None,
                          active_at: Optional[dict[str, float]] = None) -> np.ndarray:
    """(n_active, 3) ground positions of the muscle's active path points.

    ``active_at`` (default ``coords``) decides which conditional points are active, so a derivative can be taken
    with the active set frozen, as OpenSim's moment arm is.
    """
    poses = body_transforms(model, coords) if poses is None else poses
    sel = coords if active_at is None else active_at
    pts = [poses[p.body][:3, :3] @ np.asarray(p.location) + poses[p.body][:3, 3] for p in muscle.path if p.active(sel)]
    return np.asarray(pts)


def mtu_length(model: OsimModel, muscle: Muscle, coords: dict[str, float],
               active_at: Optional[dict[str, float]] = None) -> float:
    """True OpenSim muscle-tendon length (m): the polyline through the active path points."""
    pts = path_points_in_ground(model, muscle, coords, active_at=active_at)
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))


def moment_arm(model: OsimModel, muscle: Muscle, coords: dict[str, float], coordinate: str,
               h: float = 1e-6) -> float:
    """Moment arm −∂L/∂q (m) about ``coordinate`` by central differences with the active point set frozen at q.

    Positive: the muscle shortens as the coordinate increases, so its tension drives the coordinate positive.
    """
    plus, minus = dict(coords), dict(coords)
    plus[coordinate] += h
    minus[coordinate] -= h
    return -(mtu_length(model, muscle, plus, active_at=coords)
             - mtu_length(model, muscle, minus, active_at=coords)) / (2.0 * h)
