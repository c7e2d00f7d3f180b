"""The rotation helpers against scipy's ``Rotation`` (the independent reference)."""

import numpy as np
from scipy.spatial.transform import Rotation

from datasets.rotations import so3_log


def test_so3_log_of_one_matrix_equals_scipys_everywhere_including_near_pi():
    rng = np.random.default_rng(7)
    matrices = list(Rotation.random(2000, random_state=rng).as_matrix())
    axes = rng.normal(size=(400, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.repeat([0.0, 1e-12, 1e-6, 1e-3, 1.001e-3, 0.5, np.pi - 1e-3], 400 // 7 + 1)[:400]
    matrices += list(Rotation.from_rotvec(angles[:, None] * axes).as_matrix())
    matrices += [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    for matrix in matrices:
        ours, reference = so3_log(matrix), Rotation.from_matrix(matrix).as_rotvec()
        assert ours.shape == (3,)
        np.testing.assert_allclose(ours, reference, atol=1e-14, rtol=0)


def test_so3_log_at_pi_gives_a_vector_of_the_same_rotation():
    """At exactly pi the sign of the rotation vector is arbitrary: compare rotations."""
    rng = np.random.default_rng(8)
    axes = rng.normal(size=(200, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    for axis in axes:
        matrix = Rotation.from_rotvec(np.pi * axis).as_matrix()
        ours = so3_log(matrix)
        assert abs(np.linalg.norm(ours) - np.pi) < 1e-12
        np.testing.assert_allclose(Rotation.from_rotvec(ours).as_matrix(), matrix, atol=1e-14)


def test_so3_log_batches_and_non_orthogonal_matrices_are_scipys():
    rng = np.random.default_rng(9)
    batch = Rotation.random(5, random_state=rng).as_matrix()
    np.testing.assert_array_equal(so3_log(batch), Rotation.from_matrix(batch).as_rotvec())
    skewed = batch[0] + 1e-6 * rng.normal(size=(3, 3))
    np.testing.assert_array_equal(so3_log(skewed), Rotation.from_matrix(skewed).as_rotvec())
