"""First-order covariance of the sensor-based filter's derived Earth-frame pose (planar).

Guerreiro et al. (2013) give the Earth-frame trajectory and map as a by-product of the
robocentric filter (sections I and V, Fig. 8) and no uncertainty for them; this module is our
extension, so that the pose NEES of the sensor-based filter can be scored like any other
estimator's. ``earth_frame.EarthFrameTracker`` derives the pose in two ways, and each gets
its first-order covariance here, in world coordinates ``[dp (2), dtheta]``
(``p_true = p + dp``, ``theta_true = theta + dtheta``; the filter converts it to the
interface's right perturbation at the boundary, ``filters.ekf_slam.boundary``):

- **Composition** ``p_k = p_{k-1} + R_{k-1} t``, ``theta_k = theta_{k-1} + phi`` of an
  increment ``(t, phi)`` known to ``Q`` (body frame k-1): ``P_k = F P F^T + G Q G^T`` with
  ``F = [[I, J R_{k-1} t], [0, 1]]``, ``G = diag(R_{k-1}, 1)``, ``J = [[0, -1], [1, 0]]``.
  ``Q`` is the motion's uncertainty over the increment: with odometry, from the odometry's
  own per-sample covariance (the dataset's noise model, ``accumulate_odometry_covariance``);
  without, from the filter's velocity and bias uncertainty (``motion_covariance``). The
  increment aligns consecutive body-frame maps whose errors are mostly shared, so the
  landmarks' stated covariances would overstate it by far.
- **Anchoring**: the pose ``(R, p)`` minimising ``sum w_i |R s_i + p - y_i|^2`` over body-frame
  landmarks ``s_i`` and their Earth-map positions ``y_i``. Perturbing the normal equations
  (Gauss-Newton at the solution, ``H_i = [I, J R s_i]``, ``M = (sum w_i H_i^T H_i)^-1``)
  gives ``dx = sum_i A_i (dy_i - R ds_i)`` with ``A_i = w_i M H_i^T`` (``alignment_gains``):
  exact to first order for *any* weights, so the scalar weights of the alignment need not be
  the inverse covariances. The current body-frame landmarks ``ds`` enter with their *joint*
  covariance from the filter (the robocentric map's errors share the vehicle's motion
  error: treating them as independent would understate the pose error).
- **Entering a landmark** ``y = R s + p`` into the Earth map: ``dy = [I, J (y - p)] dx +
  R ds``, correlated with the pose error of that moment.

The Earth map's errors are far from independent: every entry carries the pose error of its
moment, and those moments' pose errors came from anchoring on earlier entries. On UTIAS
robot 1 the Earth frame's heading was 0.4 deg off at the first entries (13 s), 2-17 deg
between 20 and 60 s, and about 7 deg for the rest of the run, a rotation of the map made
while it was built. So ``EarthErrorCovariance`` keeps the joint first-order covariance of
the pose error and of every entry's position error, as an EKF-SLAM keeps its map's (rows
added on entry, the pose rows replaced on anchoring). Two shortcuts, each measured on UTIAS
robot 1 with ids (pose NEES per run, 3 dof): entries treated as independent beyond a shared
frame error read 24.0 (each axis 3-5x optimistic after 120 s); a covariance-intersection
bound over the entries read a 107 deg heading deviation from entries known to 11 deg (their
transfers' lever arms cancel in the sum, which the bound cannot see). Left out: the
correlation between the current body-frame estimate of a landmark and its own Earth entry
(the same filter estimate, some time apart); it is positive, so leaving it out errs on the
large side.

``tests/test_sensor_based_earth_pose_covariance.py`` checks these against Monte Carlo runs of
the operations they linearise; ``tests/test_utias_sensor_based.py`` scores the pose NEES on
UTIAS.
"""

from __future__ import annotations

import numpy as np

SKEW = np.array([[0.0, -1.0], [1.0, 0.0]])
"""``J``: ``d/dtheta R(theta) = J R(theta)``."""


def motion_covariance(
    velocity_gain: np.ndarray,
    duration_s: float,
    vehicle_covariance: np.ndarray,
    velocity_density: float | np.ndarray,
    bias_density: float,
    gyro_noise_density: float,
) -> np.ndarray:
    """Covariance (3, 3) of the filter's dead-reckoned planar motion ``[t, phi]`` over one
    increment of ``duration_s`` (module docstring, composition).

    ``t = sum_j R_j v dt_j`` and ``phi = sum_j (omega_m - b) dt_j``: an error in the velocity
    estimate moves ``t`` by ``velocity_gain dv`` (``velocity_gain = sum_j R_j dt_j``), an
    error in the bias turns ``phi`` by ``-T db``; the random walks over the increment add
    ``sigma^2 T^3 / 3`` and the gyro's white noise ``sigma_g^2 T``.

    Args:
        velocity_gain: (2, 2) ``sum_j R_j dt_j`` [s]; duration_s: T [s].
        vehicle_covariance: (3, 3) covariance of the filter's ``[v (2), b]`` now.
        velocity_density: sigma_v [m/s/sqrt(s)], scalar or per body axis (2,).
        bias_density: sigma_b [rad/s/sqrt(s)]; gyro_noise_density: [rad/s/sqrt(Hz)].
    """
    jacobian = np.zeros((3, 3))
    jacobian[:2, :2] = velocity_gain
    jacobian[2, 2] = -duration_s
    result = jacobian @ vehicle_covariance @ jacobian.T
    cube = duration_s**3 / 3.0
    result[:2, :2] += np.diag(np.broadcast_to(np.square(velocity_density), (2,)) * cube)
    result[2, 2] += bias_density**2 * cube + gyro_noise_density**2 * duration_s
    return 0.5 * (result + result.T)


def accumulate_odometry_covariance(
    accumulated: np.ndarray,
    rotation: np.ndarray,
    step: np.ndarray,
    dt: float,
    covariance: np.ndarray,
    relative_pose: bool,
) -> np.ndarray:
    """The covariance (3, 3) of the motion ``[t, phi]`` accumulated since the last scan (in
    that scan's body frame) after one more planar odometry sample: the composition above,
    ``F Q F^T + G Sigma G^T`` with the sample's own translation ``step`` (2,) [m] (its start
    frame) as the lever of the heading error so far.

    Args:
        accumulated: (3, 3) before the sample; rotation: (2, 2) the motion's rotation at the
            sample's start.
        covariance: the sample's own: (3, 3) of a relative pose ``[x, y, theta]``, or (2, 2)
            of a velocity ``[v_forward, omega]`` held for ``dt`` [s].
    """
    transition = np.eye(3)
    transition[:2, 2] = SKEW @ rotation @ step
    gain = np.zeros((3, 3 if relative_pose else 2))
    if relative_pose:
        gain[:2, :2] = rotation
        gain[2, 2] = 1.0
    else:
        gain[:2, 0] = rotation[:, 0] * dt
        gain[2, 1] = dt
    return transition @ accumulated @ transition.T + gain @ covariance @ gain.T


def alignment_gains(
    rotation: np.ndarray, body_positions: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """``A_i`` (n, 3, 2) of an anchoring alignment (module docstring): the pose error
    ``[dp, dtheta]`` is ``sum_i A_i (dy_i - R ds_i)``.

    Args:
        rotation: (2, 2) the anchored body-to-Earth rotation ``R``.
        body_positions: (n, 2) ``s_i`` [m]; weights: (n,) ``w_i`` (any positive scale).
    """
    design = np.zeros((len(body_positions), 2, 3))
    design[:, :, :2] = np.eye(2)
    design[:, :, 2] = body_positions @ (SKEW @ rotation).T
    information = np.einsum("n,nki,nkj->ij", weights, design, design)
    return weights[:, None, None] * np.einsum("ij,nkj->nik", np.linalg.inv(information), design)


class EarthErrorCovariance:
    """Joint first-order covariance of the planar Earth pose's error ``[dp, dtheta]`` (world
    coordinates) and of every Earth-map entry's position error (module docstring).

    Attributes:
        matrix: (3 + 2 m, 3 + 2 m), the pose first, then the m entries in ``slots`` order.
        slots: entry key -> its index among the entries.
    """

    def __init__(self, pose_covariance: np.ndarray) -> None:
        self.matrix = np.array(pose_covariance, dtype=float).reshape(3, 3)
        self.slots: dict[int, int] = {}

    @property
    def pose(self) -> np.ndarray:
        """The pose error's covariance (3, 3)."""
        return self.matrix[:3, :3].copy()

    def _rows(self, keys: list[int]) -> np.ndarray:
        return np.array([3 + 2 * self.slots[key] + axis for key in keys for axis in (0, 1)])

    def compose(
        self, rotation: np.ndarray, translation: np.ndarray, increment_covariance: np.ndarray
    ) -> None:
        """``p += R t``, ``theta += phi`` (module docstring, composition).

        Args:
            rotation: (2, 2) the pose's rotation before; translation: (2,) the increment in
                that body frame [m]; increment_covariance: (3, 3) of ``[t, phi]``.
        """
        transition = np.eye(3)
        transition[:2, 2] = SKEW @ rotation @ translation
        noise_gain = np.eye(3)
        noise_gain[:2, :2] = rotation
        self.matrix[:3, :] = transition @ self.matrix[:3, :]
        self.matrix[:, :3] = self.matrix[:, :3] @ transition.T
        self.matrix[:3, :3] += noise_gain @ increment_covariance @ noise_gain.T
        self._symmetrise_pose()

    def enter(
        self,
        key: int,
        earth_position: np.ndarray,
        pose_position: np.ndarray,
        own_covariance: np.ndarray,
    ) -> None:
        """Add an entry ``y = R s + p`` (module docstring, entering a landmark).

        Args:
            earth_position: (2,) ``y`` [m]; pose_position: (2,) ``p`` now [m];
            own_covariance: (2, 2) ``R C_s R^T``, its body-frame covariance in Earth axes.
        """
        lever = np.zeros((2, 3))
        lever[:, :2] = np.eye(2)
        lever[:, 2] = SKEW @ (earth_position - pose_position)
        cross = lever @ self.matrix[:3, :]  # (2, N)
        block = cross[:, :3] @ lever.T + own_covariance
        size = len(self.matrix)
        grown = np.zeros((size + 2, size + 2))
        grown[:size, :size] = self.matrix
        grown[size:, :size] = cross
        grown[:size, size:] = cross.T
        grown[size:, size:] = 0.5 * (block + block.T)
        self.matrix = grown
        self.slots[int(key)] = (size - 3) // 2

    def anchor(
        self, keys: list[int], gains: np.ndarray, rotation: np.ndarray, body_joint: np.ndarray
    ) -> None:
        """Replace the pose error by an anchoring's ``sum_i A_i (dy_i - R ds_i)``.

        Args:
            keys: the n entries aligned; gains: (n, 3, 2) ``A_i`` (``alignment_gains``);
            rotation: (2, 2) ``R``; body_joint: (2n, 2n) joint covariance of the ``s_i``.
        """
        rows = self._rows(keys)
        transfer = gains.transpose(1, 0, 2).reshape(3, -1)  # acts on the entries' rows
        body_gain = (gains @ rotation).transpose(1, 0, 2).reshape(3, -1)
        cross = transfer @ self.matrix[rows, :]  # the new pose error with everything, (3, N)
        pose = cross[:, rows] @ transfer.T + body_gain @ body_joint @ body_gain.T
        self.matrix[:3, 3:] = cross[:, 3:]
        self.matrix[3:, :3] = cross[:, 3:].T
        self.matrix[:3, :3] = pose
        self._symmetrise_pose()

    def forget(self, key: int) -> None:
        """Drop an entry's rows (the landmark left the Earth map)."""
        slot = self.slots.pop(int(key), None)
        if slot is None:
            return
        keep = np.delete(np.arange(len(self.matrix)), [3 + 2 * slot, 4 + 2 * slot])
        self.matrix = self.matrix[np.ix_(keep, keep)]
        self.slots = {k: s - 1 if s > slot else s for k, s in self.slots.items()}

    def _symmetrise_pose(self) -> None:
        """Only the pose block can drift from symmetry: every other change writes a row and
        its column from the same values."""
        self.matrix[:3, :3] = 0.5 * (self.matrix[:3, :3] + self.matrix[:3, :3].T)
