"""The emulator's compiled forward kinematics (``sim_table.forward_kinematics``): the table model's Newton pose by
pose, to within its tolerance, and the table model's errors where it cannot solve."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import AnalysisInputError
from analysis.table.limits import TableModelError
from analysis.table.model import TableModel
from sim_table.forward_kinematics import ForwardKinematics

TABLE = TableModel()


@pytest.fixture(scope="module")
def kinematics() -> ForwardKinematics:
    """The default table's forward kinematics, made (its kernel compiled or loaded) by the first test that needs it, not
    at collection, which every xdist worker does for every module."""
    return ForwardKinematics(TABLE)


REACH = np.array([0.25, 0.25, 0.18, 0.17, 0.17, 0.1])  # m, rad: the envelope, yaw 0.1 rad


def test_the_poses_are_the_table_model_s_from_a_near_guess_and_from_home(kinematics: ForwardKinematics) -> None:
    rng = np.random.default_rng(41)
    poses = rng.uniform(-1.0, 1.0, (200, 6)) * REACH
    lengths = TABLE.leg_lengths(poses)
    near = poses + rng.normal(0.0, 1e-8, poses.shape)
    solved = kinematics.poses(lengths, near)
    assert np.abs(solved - TABLE.pose_from_leg_lengths(lengths, guess=near)).max() < 1e-12
    assert np.abs(TABLE.leg_lengths(solved) - lengths).max() <= 1e-12
    from_home = kinematics.poses(lengths, np.zeros(6))
    assert np.abs(from_home - poses).max() < 1e-10


def test_one_pose_and_a_batch_of_batches_keep_their_shapes(kinematics: ForwardKinematics) -> None:
    pose = np.array([0.01, -0.02, 0.03, 0.01, -0.02, 0.005])
    assert kinematics.poses(TABLE.leg_lengths(pose), np.zeros(6)).shape == (6,)
    stacked = np.stack([np.stack([pose, -pose])] * 3)  # (3, 2, 6)
    assert np.allclose(kinematics.poses(TABLE.leg_lengths(stacked), np.zeros(6)), stacked, atol=1e-10)


def test_lengths_it_cannot_solve_get_the_table_model_s_error(kinematics: ForwardKinematics) -> None:
    with pytest.raises(AnalysisInputError, match="leg lengths must be > 0 m"):
        kinematics.poses(-np.ones((1, 6)), np.zeros(6))
    with pytest.raises(TableModelError, match="forward kinematics"):
        kinematics.poses(np.array([[1.0, 1.0, 1.0, 5.0, 5.0, 5.0]]), np.zeros(6), max_iter=5)
