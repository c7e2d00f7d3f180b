"""TUM/KITTI round trips and bad-input errors of the trajectory file formats."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from datasets.errors import InputError
from datasets.rotations import quat_wxyz_from_rotation
from datasets.trajectory import Trajectory
from datasets.trajectory_io import read_kitti, read_tum, write_kitti, write_tum


def random_trajectory(seed: int, count: int = 20, dimension: int = 3) -> Trajectory:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.05, 0.2, count))
    positions = rng.normal(size=(count, dimension))
    if dimension == 3:
        rotations = quat_wxyz_from_rotation(Rotation.random(count, random_state=seed))
    else:
        rotations = rng.uniform(-np.pi, np.pi, count)
    return Trajectory(t, positions, rotations)


def test_tum_round_trip_keeps_poses(tmp_path):
    trajectory = random_trajectory(1)
    loaded = read_tum(write_tum(tmp_path / "a.tum", trajectory))
    assert np.allclose(loaded.t, trajectory.t, atol=1e-9)
    assert np.allclose(loaded.positions, trajectory.positions, atol=1e-9)
    assert np.allclose(loaded.rotation_matrices(), trajectory.rotation_matrices(), atol=1e-8)


def test_planar_trajectory_written_as_rotation_about_z(tmp_path):
    trajectory = random_trajectory(2, dimension=2)
    loaded = read_tum(write_tum(tmp_path / "p.tum", trajectory))
    assert np.allclose(loaded.positions[:, 2], 0.0)
    assert np.allclose(
        loaded.rotation_matrices()[:, :2, :2], trajectory.rotation_matrices(), atol=1e-8
    )


def test_kitti_round_trip(tmp_path):
    trajectory = random_trajectory(3)
    loaded = read_kitti(write_kitti(tmp_path / "k.txt", trajectory), t=trajectory.t)
    assert np.allclose(loaded.homogeneous(), trajectory.homogeneous(), atol=1e-8)


@pytest.mark.parametrize(
    "content, message",
    [
        ("0 1 2 3 0 0 0 1\n1 2 3\n", ":2: expected 8 numbers"),
        ("0 1 2 x 0 0 0 1\n", ":1: not a number"),
        ("# only a comment\n", "no poses"),
        ("0 1 2 3 0 0 0 0\n", "zero quaternion"),
        ("0 nan 2 3 0 0 0 1\n", ":1: non-finite"),
    ],
)
def test_malformed_tum_names_file_and_line(tmp_path, content, message):
    path = tmp_path / "bad.tum"
    path.write_text(content)
    with pytest.raises(InputError, match=message) as error:
        read_tum(path)
    assert "bad.tum" in str(error.value)


def test_missing_file_is_input_error(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_tum(tmp_path / "absent.tum")


def test_trajectory_rejects_inconsistent_shapes():
    with pytest.raises(ValueError, match="disagree"):
        Trajectory(np.zeros(3), np.zeros((2, 3)), np.zeros((3, 4)))


def test_atomic_writes_get_the_mode_the_umask_gives(tmp_path) -> None:
    import os
    import stat

    from datasets.trajectory_io import write_atomic

    previous = os.umask(0o022)
    try:
        path = write_atomic(tmp_path / "out.txt", "x")
    finally:
        os.umask(previous)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert not list(tmp_path.glob(".*.tmp"))
