"""The MJCF arm in the authors' planar frame: its bones and muscle paths at joint angles q, projected onto the plane
of motion (what :mod:`jaxarm.viz.video` draws and :mod:`jaxarm.viz.mujoco_render` frames its camera by)."""
from __future__ import annotations

import numpy as np


class MuscleProjector:
    """Muscle paths and bones of the MJCF arm at joint angles q, in the authors' planar frame (m).

    The 3-D model is mapped to the plane by the affine map that best carries its shoulder, elbow and hand
    positions to the authors' forward kinematics (least squares over postures spanning the joint ranges): the
    model's arm moves in one plane, so the map is its projection onto that plane up to the frames' offsets."""

    def __init__(self, muscle_names, segments_m):
        import mujoco

        from jaxarm.arm.geometry import load_mjmodel, tendon_names

        self.segments_m = tuple(segments_m)
        self.mujoco = mujoco
        self.model = load_mjmodel()
        self.data = mujoco.MjData(self.model)
        names = tendon_names(self.model)
        missing = [m for m in muscle_names if m not in names]
        if missing:
            raise ValueError(f"muscles {missing} of the run are not tendons of the MJCF model")
        self.tendons = [names.index(m) for m in muscle_names]
        self.bodies = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, b) for b in ("humerus", "ulna", "hand")]
        xs, ys = [], []
        for q1 in np.linspace(-0.5, 1.8, 6):
            for q2 in np.linspace(0.0, 2.4, 6):
                q = np.array([q1, q2])
                xs.append(self.joints3d(q))
                ys.append(planar_joints(q, segments_m))
        x3 = np.concatenate(xs)
        ones = np.ones((len(x3), 1))
        self.map, *_ = np.linalg.lstsq(np.hstack([x3, ones]), np.concatenate(ys), rcond=1e-6)

    def joints3d(self, q):
        """(3, 3) positions of the humerus, ulna and hand bodies at joint angles q (rad), the model's frame, m."""
        self.data.qpos[:] = q
        self.mujoco.mj_fwdPosition(self.model, self.data)
        return self.data.xpos[self.bodies].copy()

    def project(self, x3):
        return np.hstack([x3, np.ones((len(x3), 1))]) @ self.map

    def frame(self, q):
        """(bones (3, 2): shoulder, elbow, hand; [muscle path (points, 2)] in the run's muscle order)."""
        bones = self.project(self.joints3d(q))
        wrap = self.data.wrap_xpos.reshape(-1, 3)
        paths = [self.project(wrap[self.data.ten_wrapadr[i]: self.data.ten_wrapadr[i] + self.data.ten_wrapnum[i]])
                 for i in self.tendons]
        return bones, paths


def planar_joints(q, segments_m) -> np.ndarray:
    """(3, 2) shoulder, elbow and hand of the authors' planar forward kinematics (jaxarm.arm.base.hand_position), m,
    in NumPy: one frame's few numbers are not worth a JAX dispatch."""
    l1, l2 = segments_m
    elbow = l1 * np.array([np.cos(q[0]), np.sin(q[0])])
    return np.stack([np.zeros(2), elbow, elbow + l2 * np.array([np.cos(q[0] + q[1]), np.sin(q[0] + q[1])])])
