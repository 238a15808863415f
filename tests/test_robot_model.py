"""The WAM MJCF: built from Barrett's published numbers, committed asset in sync, planar J1/J4 geometry."""
import math

import mujoco
import numpy as np
import pytest

from jaxarm.robot.wam_model import (ARMATURE_KGM2, ASSET_DIR, JOINT_RANGE_RAD, LINK_INERTIA_KGM2, LINK_MASS_KG,
                                    STOP_INSET_RAD, VARIANTS, build_mjcf, load_model, mjcf_for)
from jaxarm.robot.config import PhysicsConfig


@pytest.mark.parametrize("variant", VARIANTS)
def test_committed_asset_matches_generator(variant):
    # The asset is for viewers; the simulator builds from code. They must not drift apart.
    assert (ASSET_DIR / f"{variant}.xml").read_text() == mjcf_for(PhysicsConfig(variant=variant))


def test_model_uses_barrett_masses_ranges_and_armature():
    m = load_model()
    assert m.nq == 4 and m.nu == 4
    np.testing.assert_allclose(m.body_mass[2:6], LINK_MASS_KG)        # world, base_frame, link1..4
    assert m.body_mass.sum() == pytest.approx(17.51, abs=0.01)        # wam.md §1.2: 17.5 kg moving mass
    np.testing.assert_allclose(m.jnt_range, np.asarray(JOINT_RANGE_RAD) + [STOP_INSET_RAD, -STOP_INSET_RAD])
    np.testing.assert_allclose(m.dof_armature, ARMATURE_KGM2)
    for ixx, iyy, izz, ixy, ixz, iyz in LINK_INERTIA_KGM2:           # each published tensor is physical
        assert np.all(np.linalg.eigvalsh([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) > 0)
    assert not m.geom_contype.any() and not m.geom_conaffinity.any()  # contacts off: geometry is display only
    assert "mesh" not in build_mjcf()                                 # primitives only, no GPL meshes


@pytest.mark.parametrize("variant", VARIANTS)
def test_j1_and_j4_vertical_so_the_arm_is_planar(variant):
    m = load_model(variant=variant)
    d = mujoco.MjData(m)
    heights = []
    for q1, q4 in [(0.0, 0.0), (0.6, 1.5), (1.7, 2.4), (-0.2, 0.1)]:
        d.qpos[:] = [q1, math.pi / 2, math.pi / 2, q4]
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(d.xaxis[0], [0, 0, 1], atol=1e-9)   # J1 axis
        np.testing.assert_allclose(d.xaxis[3], [0, 0, 1], atol=1e-9)   # J4 axis
        heights.append(d.site_xpos[0, 2])
        # Gravity loads only J2 and J3 in this plane.
        assert abs(d.qfrc_gravcomp[0]) < 1e-9 and abs(d.qfrc_gravcomp[3]) < 1e-9
        # Positive J1 and J4 turn the hand counter-clockwise seen from above, like the virtual arm's angles.
        hand_angle = math.atan2(d.site_xpos[0, 1], d.site_xpos[0, 0])
        assert hand_angle == pytest.approx(q1 + math.atan2(0.36 * math.sin(q4), 0.55 + 0.36 * math.cos(q4)),
                                           abs=0.1)
    assert np.ptp(heights) < 1e-9


def test_stretched_reach_is_upper_arm_plus_tool_plate():
    m = load_model()
    d = mujoco.MjData(m)
    d.qpos[:] = [0.0, math.pi / 2, math.pi / 2, 0.0]
    mujoco.mj_forward(m, d)
    # 0.55 m upper arm + 0.36 m tool plate (wam4.conf); the 0.045 m offsets cancel when straight.
    assert np.linalg.norm(d.site_xpos[0]) == pytest.approx(0.91, abs=1e-9)


def test_unknown_variant_rejected():
    with pytest.raises(ValueError, match="variant"):
        build_mjcf(variant="wam5")
