"""Robot configuration: golden libbarrett values, validation, joint map, jitter fit."""
import math

import numpy as np
import pytest

from jaxarm.config.validate import ConfigError
from jaxarm.robot.config import (VALUES, ControllerConfig, JitterConfig, JointMap, PhysicsConfig, ReceiverConfig,
                                 WamSimConfig, values_markdown)


def test_libbarrett_gains_are_the_wam4_conf_values():
    # Golden table: libbarrett config/wam4.conf, as listed in wam.md §2.
    c = ControllerConfig()
    assert c.control_period_s == 0.002
    assert c.jp_kp == (900, 2500, 600, 500)
    assert c.jp_ki == (2.5, 5, 2.5, 0.5)
    assert c.jp_kd == (10, 20, 10, 2.5)
    assert c.jp_limit_nm == (25, 20, 15, 15)
    assert c.jv_kp == (42, 42, 18, 18)
    assert c.jv_ki == (0, 0, 0, 0) and c.jv_kd == (0, 0, 0, 0)
    assert c.jv_limit_nm == (25, 20, 15, 15)
    assert c.jv_torque_lowpass_rad_s == (180, 180, 56, 56)
    assert c.velocity_filter_rad_s == (180, 180, 180, 180)


def test_every_value_has_a_source_and_the_table_renders():
    for name, (value, unit, source) in VALUES.items():
        assert source and unit, name
    table = values_markdown()
    assert table.count("\n") == len(VALUES) + 1 and "wam4.conf joint_velocity_control" in table


def test_jitter_gamma_is_moment_fit_to_paper():
    j = JitterConfig()
    assert j.shape == pytest.approx(7.133, abs=1e-3)
    assert j.scale_ms == pytest.approx(2.1155, abs=1e-4)
    assert j.shape * j.scale_ms == pytest.approx(15.09)                 # mean
    assert math.sqrt(j.shape) * j.scale_ms == pytest.approx(5.65)       # SD


@pytest.mark.parametrize("make, field", [
    (lambda: ControllerConfig(mode="torque"), "mode"),
    (lambda: ControllerConfig(pos_to_vel_gain_per_s=0.0), "pos_to_vel_gain_per_s"),
    (lambda: ControllerConfig(jv_kp=(42, 42, 18)), "jv_kp"),
    (lambda: ControllerConfig(jp_kp=(1, 2, 3, float("nan"))), "jp_kp"),
    (lambda: ReceiverConfig(timeout_s=0.0), "timeout_s"),
    (lambda: ReceiverConfig(on_timeout="explode"), "on_timeout"),
    (lambda: PhysicsConfig(substeps=0), "substeps"),
    (lambda: PhysicsConfig(variant="wam3"), "variant"),
    (lambda: JointMap(elbow_joint=0), "elbow_joint"),
    (lambda: JointMap(shoulder_scale=0.0), "shoulder_scale"),
    (lambda: WamSimConfig(initial_virtual_rad=(3.0, 1.0)), "initial_virtual_rad"),
    (lambda: JitterConfig(sd_ms=0.0), "sd_ms"),
])
def test_bad_values_raise_one_config_error_naming_the_field(make, field):
    with pytest.raises(ConfigError, match=field):
        make()


def test_joint_map_round_trip_and_hold_pose():
    jm = JointMap(shoulder_scale=-1.0, shoulder_offset_rad=0.3, elbow_offset_rad=-0.1)
    virt = np.array([[0.62, 1.53], [-0.1, 2.4]])
    wam = jm.to_wam(virt)
    np.testing.assert_allclose(wam[:, 1:3], math.pi / 2)                # J2 = J3 = pi/2 held
    np.testing.assert_allclose(wam[:, 0], 0.3 - virt[:, 0])
    np.testing.assert_allclose(jm.to_virtual(wam), virt)
    # Default: shoulder -> J1, elbow -> J4, identity.
    np.testing.assert_allclose(JointMap().to_wam([0.62, 1.53]), [0.62, math.pi / 2, math.pi / 2, 1.53])
