"""The musculoskeletal arm rendered by MuJoCo offscreen, for ``jaxarm video --renderer mujoco``.

MuJoCo renders the MJCF model (``jaxarm/arm/assets/arm.xml``) at each frame's joint angles: its 22 spatial tendons
(the muscle paths) coloured and thickened by activation, and, drawn into the scene as extra geoms, the bones
(shoulder-elbow-hand), the target's success disc and the hand's trace. The camera looks at the arm's plane of
motion along its normal, with the image's x and y axes on the authors' planar x and y (so the picture has the
orientation of the matplotlib renderer's).

Offscreen rendering needs an OpenGL that works without a display: ``MUJOCO_GL=egl`` (a GPU driver, or Mesa's) or
``MUJOCO_GL=osmesa`` (Mesa's software renderer, e.g. Debian's ``libosmesa6``), set before Python starts (MuJoCo
reads it at import). Where neither works, :class:`RenderUnavailable` says so in one line.
"""
from __future__ import annotations

import os

import numpy as np

from jaxarm.viz.arm_projection import MuscleProjector

#: Tendon width at rest and added at full activation, m (MuJoCo draws a spatial tendon as capsules of this radius).
TENDON_WIDTH_M = (0.0015, 0.005)
#: Bone width, m.
BONE_WIDTH_M = 0.008
#: Most hand-trace segments drawn per frame (the trace is subsampled beyond it).
MAX_TRACE_SEGMENTS = 300


class RenderUnavailable(RuntimeError):
    """MuJoCo cannot render offscreen on this machine."""


def _unit(v):
    return v / np.linalg.norm(v)


class MujocoArmRenderer:
    """Frames of the MJCF arm, ``(height, width, 3)`` uint8, at joint angles q (rad) with muscle activations a.

    Args:
        projector (MuscleProjector): the run's muscles (in the order of the activations given to :meth:`frame`)
            and the map from the model's frame to the planar one the target and hand are given in.
        width (int): the image's width in pixels.
        height (int): the image's height in pixels.
        target_m (ArrayLike): the target's centre (planar, m).
        radius_m (float): the target's success radius, m.
    """

    def __init__(self, projector: MuscleProjector, width: int, height: int, target_m, radius_m: float):
        import mujoco

        self.mujoco = mujoco
        self.projector = projector
        lin = self.projector.map[:3]                                       # planar = x3 @ lin + offset
        # lin's columns lie in the plane of motion (the least-squares map's minimum-norm solution), so
        # lift = lin (lin^T lin)^-1 carries a planar displacement to the 3-D one in that plane.
        lift = lin @ np.linalg.inv(lin.T @ lin)
        shoulder3 = self.projector.joints3d(np.zeros(2))[0]
        origin = self.projector.project(shoulder3[None])[0]
        self.to3d = lambda p: shoulder3 + (np.asarray(p, float) - origin) @ lift.T
        ex, ey = _unit(lift[:, 0]), _unit(lift[:, 1])
        normal = _unit(np.cross(ex, ey))
        ey = np.cross(normal, ex)                                          # exactly orthonormal
        # The view holds the matplotlib renderer's box, x in [-reach, reach], y in [-0.15, reach] (planar, m).
        reach = float(sum(projector.segments_m)) + 0.05
        centre = self.to3d([0.0, (reach - 0.15) / 2])
        fovy_deg = 45.0
        half_height = 1.05 * max((reach + 0.15) / 2, reach * height / width)
        distance = half_height / np.tan(np.radians(fovy_deg / 2))
        spec = mujoco.MjSpec.from_file(str(_mjcf_path()))
        spec.worldbody.add_camera(name="video", pos=centre + distance * normal, quat=_quat(ex, ey, normal),
                                  fovy=fovy_deg)
        spec.visual.global_.offwidth = max(width, 64)
        spec.visual.global_.offheight = max(height, 64)
        spec.visual.headlight.ambient = [0.45, 0.45, 0.45]              # the model has no lights of its own
        spec.visual.headlight.diffuse = [0.7, 0.7, 0.7]
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.tendons = self.projector.tendons
        self.bodies = self.projector.bodies
        self.model.tendon_rgba[:] = 0.0                                    # only the run's muscles are drawn
        try:
            self.renderer = mujoco.Renderer(self.model, height, width, max_geom=2000)
        except Exception as e:  # noqa: BLE001 - GL errors come as many types, from several bindings
            gl = os.environ.get("MUJOCO_GL", "unset")
            raise RenderUnavailable(
                f"--renderer mujoco: MuJoCo cannot render offscreen here (MUJOCO_GL={gl}: {type(e).__name__}); set "
                "MUJOCO_GL=egl or MUJOCO_GL=osmesa (with its libraries) before starting, or use the default "
                "--renderer matplotlib") from None
        self.options = mujoco.MjvOption()
        self.options.flags[mujoco.mjtVisFlag.mjVIS_TENDON] = True
        self.target3 = self.to3d(target_m)
        self.radius_m = float(radius_m)
        self.disc_mat = np.column_stack([ex, ey, normal]).reshape(-1)
        self.normal = normal

    def _add(self, init):
        scene = self.renderer.scene
        if scene.ngeom >= scene.maxgeom:
            return
        init(scene.geoms[scene.ngeom])
        scene.ngeom += 1

    def frame(self, q, activation, hand_path_m, wam_joints_m=None) -> np.ndarray:
        """The image at joint angles ``q`` (2,) rad, activations ``activation`` (muscles,) in [0, 1], with the hand's
        trace ``hand_path_m`` (points, 2) planar m and, if given, the WAM's shoulder, elbow and hand ``wam_joints_m``
        (3, 2) planar m drawn as a second arm."""
        mj = self.mujoco
        self.data.qpos[:] = q
        mj.mj_fwdPosition(self.model, self.data)
        a = np.clip(np.asarray(activation, float), 0.0, 1.0)
        rgba = np.column_stack([np.full_like(a, 0.95), 0.85 * (1 - a), 0.85 * (1 - a), np.ones_like(a)])
        self.model.tendon_rgba[self.tendons] = rgba
        self.model.tendon_width[self.tendons] = TENDON_WIDTH_M[0] + TENDON_WIDTH_M[1] * a
        self.renderer.update_scene(self.data, camera="video", scene_option=self.options)
        lift = 0.01 * self.normal                                          # in front of the plane, towards the camera
        self._add(lambda g: mj.mjv_initGeom(g, mj.mjtGeom.mjGEOM_CYLINDER, np.array([self.radius_m, self.radius_m,
                                                                                      0.0005]),
                                            self.target3 - lift, self.disc_mat, np.array([1.0, 0.2, 0.2, 0.35])))
        joints = self.data.xpos[self.bodies]
        for a3, b3 in zip(joints[:-1], joints[1:]):
            self._add(lambda g, a3=a3, b3=b3: _connector(mj, g, BONE_WIDTH_M, a3, b3, (0.3, 0.3, 0.3, 1.0)))
        if wam_joints_m is not None:
            wam3 = [self.to3d(p) + 2 * lift for p in wam_joints_m]
            for a3, b3 in zip(wam3[:-1], wam3[1:]):
                self._add(lambda g, a3=a3, b3=b3: _connector(mj, g, BONE_WIDTH_M / 2, a3, b3, (0.6, 0.4, 0.85, 1.0)))
        path = np.asarray(hand_path_m, float)
        if len(path) > MAX_TRACE_SEGMENTS + 1:
            path = path[np.linspace(0, len(path) - 1, MAX_TRACE_SEGMENTS + 1).round().astype(int)]
        pts = [self.to3d(p) + lift for p in path]
        for a3, b3 in zip(pts[:-1], pts[1:]):
            self._add(lambda g, a3=a3, b3=b3: _connector(mj, g, 0.002, a3, b3, (0.35, 0.75, 1.0, 1.0)))
        return self.renderer.render()

    def close(self):
        self.renderer.close()


def _connector(mj, geom, width, a3, b3, rgba):
    mj.mjv_initGeom(geom, mj.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).reshape(-1),
                    np.asarray(rgba, np.float32))
    mj.mjv_connector(geom, mj.mjtGeom.mjGEOM_CAPSULE, width, np.asarray(a3, float), np.asarray(b3, float))


def _quat(ex, ey, ez) -> np.ndarray:
    """The unit quaternion of the rotation whose columns are ``ex, ey, ez`` (a camera's frame: x right, y up,
    looking along -z)."""
    import mujoco

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([ex, ey, ez]).reshape(-1))
    return quat


def _mjcf_path():
    from jaxarm.arm.geometry import MJCF_PATH

    return MJCF_PATH
