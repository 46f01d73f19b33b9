"""The physics plant's robot and simulation numbers (``PhysicsParams``): refused by name when they
cannot make a model, checked against their datasheet derivations, and the calibration cache's key
of a physics plant held where it was before these checks (they add no field)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from koopman_envs.params import PARAMS, PHYSICS

#: the Dynamixel XM430-W210-T at 12 V (ROBOTIS e-Manual): no-load speed [rpm], stall torque [N m]
XM430_NO_LOAD_RPM, XM430_STALL_TORQUE = 77.0, 3.0
#: ``turtlebot3_description``'s wheel link inertia [kg m^2]: about the radial axes, about the axle
URDF_WHEEL_RADIAL, URDF_WHEEL_AXIAL = 1.1175580e-5, 2.0712558e-5


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"timestep": 0.003}, r"timestep=0.003 must divide the control period PARAMS.dt=0.1 into whole"),
        ({"timestep": 0.3}, r"timestep=0.3 must divide the control period"),
        ({"timestep": 0.0}, r"timestep=0.0 must be a finite number > 0"),
        ({"mass": -1.8}, r"mass=-1.8 must be a finite number > 0"),
        ({"wheel_radius": 0.0}, r"wheel_radius=0.0 must be a finite number > 0"),
        ({"armature": math.nan}, r"armature=nan must be a finite number > 0"),
        ({"motor_time_constant": math.inf}, r"motor_time_constant=inf must be a finite number > 0"),
        ({"com_offset": -0.01}, r"com_offset=-0.01 must be a finite number >= 0"),
        ({"speed_ki": -0.6}, r"speed_ki=-0.6 must be a finite number >= 0"),
        ({"gear_factor": True}, r"gear_factor=True must be a finite number > 0"),
    ],
)
def test_a_value_that_cannot_make_a_model_is_refused_by_name(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(PHYSICS, **changes)


@pytest.mark.parametrize("timestep", [0.005, 0.0025, 0.01, 0.02, 0.1])
def test_a_timestep_that_divides_the_period_is_taken(timestep: float) -> None:
    params = dataclasses.replace(PHYSICS, timestep=timestep, com_offset=0.0, speed_ki=0.0)
    assert params.substeps * timestep == pytest.approx(PARAMS.dt)


def test_the_motor_limits_are_the_datasheets_geared_by_gear_factor() -> None:
    """Fields, not properties (the calibration key hashes the fields), so held here instead."""
    assert PHYSICS.wheel_speed_max == pytest.approx(
        XM430_NO_LOAD_RPM * 2 * math.pi / 60 * PHYSICS.gear_factor
    )
    assert PHYSICS.wheel_torque_max == pytest.approx(XM430_STALL_TORQUE / PHYSICS.gear_factor)
    # the speed limit leaves room for the paper's envelope: full speed and a full turn, outer wheel
    outer = (PARAMS.v_max + PARAMS.omega_max * PHYSICS.wheel_separation / 2) / PHYSICS.wheel_radius
    assert outer < PHYSICS.wheel_speed_max


def test_the_wheels_radial_inertia_keeps_the_urdfs_ratio_and_is_the_models() -> None:
    mujoco = pytest.importorskip("mujoco")
    from koopman_envs.sim.physics.model import robot_mjcf

    assert PHYSICS.wheel_inertia == URDF_WHEEL_AXIAL
    assert PHYSICS.wheel_radial_inertia == pytest.approx(URDF_WHEEL_RADIAL, rel=1e-12)
    doubled = dataclasses.replace(PHYSICS, wheel_inertia=2 * URDF_WHEEL_AXIAL)
    assert doubled.wheel_radial_inertia == pytest.approx(2 * URDF_WHEEL_RADIAL, rel=1e-12)
    model = mujoco.MjModel.from_xml_string(robot_mjcf(1, 0, PARAMS.robot_radius, PHYSICS))
    inertia = model.body_inertia[model.body("wheel_left_0").id]
    assert sorted(inertia) == pytest.approx(sorted([PHYSICS.wheel_radial_inertia] * 2 + [URDF_WHEEL_AXIAL]))


def test_the_calibration_key_of_a_physics_plant_is_unchanged() -> None:
    """A physics plant's signature (the calibration cache's key) hashes every PhysicsParams field:
    these, computed before the checks and the radial inertia's property were added, say no
    field was added or changed, so every cached physics calibration is still found."""
    pytest.importorskip("mujoco")
    from koopman_envs import make_plant

    tr = make_plant("KoopNav-TargetReaching-v0", plant="mujoco", slip="high", budget=1000, seed=0)
    fm = make_plant("KoopNav-Formation-v0", plant="mujoco", slip="nominal", budget=1000, seed=0)
    assert (tr.signature, fm.signature) == ("d74c92bdfec0958b", "ce5ddf8ec533cd73")
