"""Our own MJCF model of the 4-DOF Barrett WAM, built from Barrett's published numbers.

Everything here is a published fact, not copied geometry: the Denavit-Hartenberg table, masses, centres of mass and
inertia tensors come from libbarrett ``config/wam4.conf`` ("From inertial specifications Sept 2008"); joint ranges
from the WAM User Manual (D1001, Table 6); reflected rotor inertia (MJCF ``armature``) from Barrett's inertial
specification as copied in ``../shared/spec/wam.md`` §1.2. Geometry is primitive capsules for display only (the
public WAM meshes are GPL and are never vendored); contacts are off, so geometry never changes the dynamics.

Frame construction (Spong DH, ``T_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``): body *i* sits at DH frame *i-1* and
carries hinge *i* about its own z axis. The DH frame *i* is then at ``(a_i, 0, d_i)`` rotated by ``Rx(alpha_i)``
inside body *i*; that is where body *i+1* starts and where link *i*'s centre of mass and inertia (given in frame *i*)
are placed. World z is up and the base frame's origin is the J1/J2 intersection.

With ``q = (q1, pi/2, pi/2, q4)`` the J1 and J4 axes are both vertical, so J1 (horizontal shoulder) and J4 (elbow)
form a planar two-link arm in a horizontal plane and gravity loads only J2 and J3 (``wam.md`` §1.3).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: Spong DH parameters (a m, alpha rad, d m) of J1..J4; libbarrett config/wam4.conf `kinematics.moving`.
DH_TABLE: tuple[tuple[float, float, float], ...] = (
    (0.0, -math.pi / 2, 0.0),      # J1 base yaw
    (0.0, +math.pi / 2, 0.0),      # J2 shoulder pitch
    (0.045, -math.pi / 2, 0.55),   # J3 upper-arm twist
    (-0.045, +math.pi / 2, 0.0),   # J4 elbow
)
#: Tool plate of the 4-DOF arm: d = 0.36 m along z4 (libbarrett wam4.conf `toolplate`).
TOOLPLATE_D_M = 0.36
#: Link masses, kg (wam4.conf `dynamics.moving`).
LINK_MASS_KG = (10.7677, 3.8749, 1.8023, 1.0651)
#: Link centres of mass in DH frame i, m (wam4.conf).
LINK_COM_M = (
    (-4.43e-3, 121.89e-3, -0.66e-3),
    (-2.37e-3, 31.06e-3, 15.42e-3),
    (-38.26e-3, 207.51e-3, 0.03e-3),
    (10.95e-3, -0.03e-3, 140.54e-3),
)
#: Inertia about the centre of mass in DH frame i as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz), kg m^2 (wam4.conf).
LINK_INERTIA_KGM2 = (
    (134880.33e-6, 113283.69e-6, 90463.30e-6, -2130.41e-6, -124.85e-6, 685.55e-6),
    (21409.58e-6, 13778.75e-6, 15589.06e-6, 271.72e-6, 24.61e-6, -1819.20e-6),
    (59110.77e-6, 3245.50e-6, 59270.43e-6, -2496.12e-6, 7.38e-6, -17.67e-6),
    (18485.77e-6, 18916.58e-6, 1975.17e-6, 2.19e-6, -1608.68e-6, 5.15e-6),
)
#: 7-DOF WAM with wrist (libbarrett config/wam7w.conf): the J4 link "incl. wrist base" and wrist links 5-7.
#: Used by ``variant="wam7_wrist_locked"``: the wrist joints are locked at zero, so links 5-7 ride on link 4.
DH_WRIST = (
    (0.0, -math.pi / 2, 0.30),     # J5 wrist yaw
    (0.0, +math.pi / 2, 0.0),      # J6 wrist pitch
    (0.0, -math.pi / 2, 0.0609),   # J7 wrist twist
)
LINK4_7DOF = (2.17266212, (0.00553408, 0.00006822, 0.11927695),
              (0.01067491, 0.01058659, 0.00282036, 0.00004503, -0.00135557, -0.00011002))
WRIST_LINKS = (
    (0.35655692, (0.00005483, 0.02886286, 0.00148493),
     (0.00037112, 0.00019434, 0.00038209, -0.00000008, -0.00000003, -0.00001613)),
    (0.40915886, (-0.00005923, -0.01686123, 0.02419052),
     (0.00054889, 0.00023846, 0.00045133, 0.00000019, -0.00000010, -0.00004430)),
    (0.07548270, (0.00014836, 0.00007252, -0.00335185),
     (0.00003911, 0.00003877, 0.00007614, 0.00000019, 0.0, 0.0)),
)
VARIANTS = ("wam4", "wam7_wrist_locked")
#: Joint ranges, rad (WAM User Manual D1001 Table 6; wam.md §1.1).
JOINT_RANGE_RAD = ((-2.6, 2.6), (-2.0, 2.0), (-2.8, 2.8), (-0.9, 3.1))
#: The model's joint stops sit this far inside the published range, rad, so that the penetration of MuJoCo's soft
#: limit constraint (stiffened to STOP_SOLREF) never takes a joint outside the published range.
STOP_INSET_RAD = 0.02
STOP_SOLREF = (0.004, 1.0)
#: Reflected rotor inertia at the joint output, kg m^2 (Barrett inertial spec via wam.md §1.2) -> MJCF armature.
ARMATURE_KGM2 = (0.2052, 0.0944, 0.0944, 0.0346)
#: Joint names (Barrett's driver convention, wam.md §4).
JOINT_NAMES = ("wam/YawJoint", "wam/ShoulderPitchJoint", "wam/ShoulderYawJoint", "wam/ElbowJoint")
#: Capsule radii for display only, m.
_LINK_RADIUS_M = (0.06, 0.05, 0.045, 0.04)


def _rx(alpha: float) -> np.ndarray:
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _quat_rx(alpha: float) -> tuple[float, float, float, float]:
    """MuJoCo quaternion (w, x, y, z) of a rotation by ``alpha`` about x."""
    return (math.cos(alpha / 2), math.sin(alpha / 2), 0.0, 0.0)


def _fmt(values) -> str:
    return " ".join(f"{float(v):.9g}" for v in values)


def _inertial(mass, com_in_frame, inertia6, end, rot) -> str:
    """<inertial> of a link whose DH frame sits at ``end`` rotated by ``rot`` inside the body."""
    ixx, iyy, izz, ixy, ixz, iyz = inertia6
    # MJCF cannot combine fullinertia with an orientation, so rotate the tensor into the body frame.
    inertia = rot @ np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) @ rot.T
    com = end + rot @ np.array(com_in_frame)
    return (f'<inertial pos="{_fmt(com)}" mass="{mass:.9g}" fullinertia="'
            f'{_fmt((inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]))}"/>')


def build_mjcf(*, variant: str = "wam4", torque_limits_nm=(62.6, 84.2, 50.1, 26.8), damping=(0.0,) * 4, frictionloss=(0.0,) * 4,
               timestep_s: float = 0.002, base_height_m: float = 0.346) -> str:
    """Return the MJCF text of the 4-DOF WAM.

    Args:
        variant: ``"wam4"``: the 4-DOF WAM with its blank outer link and tool plate (wam4.conf).
            ``"wam7_wrist_locked"``: the 7-DOF WAM with wrist (wam7w.conf) whose J5-J7 are locked at zero, so it
            moves as a 4-DOF arm whose forearm carries the wrist (0.3 m to the wrist centre, 0.06 m to the flange).
        torque_limits_nm: total joint torque limit (controller + gravity compensation) per joint, N m. Applied as
            MJCF ``actuatorfrcrange`` on the joint, with gravity compensation routed through the actuators
            (``actuatorgravcomp``) so that the sum is what saturates, as at the pucks.
        damping, frictionloss: joint viscous damping (N m s/rad) and dry friction (N m). Barrett publishes none;
            the defaults are zero (the calibration of wam.md §6 used zero).
        timestep_s: physics time step, s.
        base_height_m: height of the J1/J2 intersection above the floor, m (barrett_model URDF: 0.346).
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant={variant!r}: must be one of {VARIANTS}")
    lines = [
        f'<mujoco model="{variant}">',
        '  <!-- jaxarm: 4-DOF Barrett WAM from published DH/inertial data (libbarrett wam4.conf, WAM manual);',
        '       primitive geometry only; generated by jaxarm.robot.wam_model.build_mjcf. -->',
        '  <compiler angle="radian" inertiafromgeom="false"/>',
        f'  <option timestep="{timestep_s:.9g}" integrator="implicitfast" gravity="0 0 -9.81"/>',
        '  <default><geom contype="0" conaffinity="0" rgba="0.75 0.75 0.78 1"/></default>',
        '  <worldbody>',
        '    <geom name="floor" type="plane" size="1.5 1.5 0.01" rgba="0.3 0.3 0.3 1"/>',
        f'    <geom name="base" type="cylinder" fromto="0 0 {-base_height_m:.6g} 0 0 -0.05" size="0.09"/>',
        f'    <body name="base_frame" pos="0 0 0">',
    ]
    indent = "      "
    closers = []
    child_pos, child_quat = (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)
    for i, (a, alpha, d) in enumerate(DH_TABLE):
        lo, hi = JOINT_RANGE_RAD[i][0] + STOP_INSET_RAD, JOINT_RANGE_RAD[i][1] - STOP_INSET_RAD
        tau = float(torque_limits_nm[i])
        end = np.array([a, 0.0, d])
        rot = _rx(alpha)
        mass, com, inertia6 = LINK_MASS_KG[i], LINK_COM_M[i], LINK_INERTIA_KGM2[i]
        if i == 3 and variant == "wam7_wrist_locked":
            mass, com, inertia6 = LINK4_7DOF
        lines += [
            f'{indent}<body name="link{i + 1}" pos="{_fmt(child_pos)}" quat="{_fmt(child_quat)}" gravcomp="1">',
            f'{indent}  <joint name="{JOINT_NAMES[i]}" type="hinge" axis="0 0 1" range="{lo:.6g} {hi:.6g}" '
            f'limited="true" solreflimit="{_fmt(STOP_SOLREF)}" armature="{ARMATURE_KGM2[i]:.6g}" damping="{float(damping[i]):.6g}" '
            f'frictionloss="{float(frictionloss[i]):.6g}" actuatorfrcrange="{-tau:.6g} {tau:.6g}" '
            f'actuatorgravcomp="true"/>',
            f'{indent}  {_inertial(mass, com, inertia6, end, rot)}',
        ]
        # Display capsules: along d (z of this body) then along a (x), ending at DH frame i.
        r = _LINK_RADIUS_M[i]
        if d:
            lines.append(f'{indent}  <geom type="capsule" fromto="0 0 0 0 0 {d:.6g}" size="{r:.3g}"/>')
        if a:
            lines.append(f'{indent}  <geom type="capsule" fromto="0 0 {d:.6g} {a:.6g} 0 {d:.6g}" size="{r:.3g}"/>')
        if not (a or d):
            lines.append(f'{indent}  <geom type="sphere" size="{r:.3g}"/>')
        child_pos, child_quat = tuple(end), _quat_rx(alpha)
        closers.append(f"{indent}</body>")
        indent += "  "
    if variant == "wam7_wrist_locked":
        # Wrist links 5-7 at q5 = q6 = q7 = 0, each a jointless body in the previous one; the hand site marks the
        # flange (wam7w toolplate: d = 0).
        for k, ((a, alpha, d), (mass, com, inertia6)) in enumerate(zip(DH_WRIST, WRIST_LINKS)):
            end, rot = np.array([a, 0.0, d]), _rx(alpha)
            lines += [f'{indent}<body name="link{k + 5}" pos="{_fmt(child_pos)}" quat="{_fmt(child_quat)}" '
                      f'gravcomp="1">', f'{indent}  {_inertial(mass, com, inertia6, end, rot)}']
            if d:
                lines.append(f'{indent}  <geom type="capsule" fromto="0 0 0 0 0 {d:.6g}" size="0.035"/>')
            else:
                lines.append(f'{indent}  <geom type="sphere" size="0.045"/>')
            child_pos, child_quat = tuple(end), _quat_rx(alpha)
            closers.append(f"{indent}</body>")
            indent += "  "
        lines.append(f'{indent}<site name="hand" pos="{_fmt(child_pos)}" size="0.02" rgba="0.9 0.2 0.2 1"/>')
        lines += list(reversed(closers))
        lines += ['    </body>', '  </worldbody>', '  <actuator>']
        return _actuators(lines, torque_limits_nm)
    # Tool plate: the forearm runs d = 0.36 m along z4; the hand site marks its end.
    lines += [
        f'{indent}<body name="toolplate" pos="{_fmt(child_pos)}" quat="{_fmt(child_quat)}">',
        f'{indent}  <geom type="capsule" fromto="0 0 0 0 0 {TOOLPLATE_D_M:.6g}" size="0.035"/>',
        f'{indent}  <site name="hand" pos="0 0 {TOOLPLATE_D_M:.6g}" size="0.02" rgba="0.9 0.2 0.2 1"/>',
        f'{indent}</body>',
    ]
    lines += list(reversed(closers))
    lines += ['    </body>', '  </worldbody>', '  <actuator>']
    return _actuators(lines, torque_limits_nm)


def _actuators(lines: list[str], torque_limits_nm) -> str:
    for i, name in enumerate(JOINT_NAMES):
        tau = float(torque_limits_nm[i])
        lines.append(f'    <motor name="m{i + 1}" joint="{name}" ctrllimited="true" ctrlrange="{-tau:.6g} {tau:.6g}"/>')
    lines += ['  </actuator>', '</mujoco>', '']
    return "\n".join(lines)


#: The committed assets (identical to ``mjcf_for(PhysicsConfig(variant=...))``, i.e. the simulator's default
#: model; a test checks they agree), for viewers and other tools.
ASSET_DIR = Path(__file__).with_name("assets")
ASSET_PATH = ASSET_DIR / "wam4.xml"


def write_mjcf(path: str | Path = ASSET_PATH, **kwargs) -> Path:
    """Write ``build_mjcf(**kwargs)`` to ``path`` and return the path."""
    path = Path(path)
    path.write_text(build_mjcf(**kwargs))
    return path


def mjcf_for(physics=None, control_period_s: float = 0.002) -> str:
    """The MJCF the simulator runs for a :class:`~jaxarm.robot.config.PhysicsConfig` (default: the defaults)."""
    from jaxarm.robot.config import PhysicsConfig

    ph = physics or PhysicsConfig()
    return build_mjcf(variant=ph.variant, torque_limits_nm=ph.torque_limit_nm, damping=ph.damping,
                      frictionloss=ph.frictionloss, timestep_s=control_period_s / ph.substeps)


def load_model(**kwargs):
    """Compile ``build_mjcf(**kwargs)`` into a fresh ``mujoco.MjModel`` (a few ms)."""
    import mujoco
    return mujoco.MjModel.from_xml_string(build_mjcf(**kwargs))


if __name__ == "__main__":  # regenerate the committed assets
    from jaxarm.robot.config import PhysicsConfig

    for name in VARIANTS:
        path = ASSET_DIR / f"{name}.xml"
        path.write_text(mjcf_for(PhysicsConfig(variant=name)))
        print(path)
