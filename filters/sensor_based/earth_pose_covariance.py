"""First-order covariance of the sensor-based filter's derived Earth-frame pose.

Guerreiro et al. (2013) give the Earth-frame trajectory and map as a by-product of the
robocentric filter (sections I and V, Fig. 8) and no uncertainty for them; this module is our
extension, so that the pose NEES of the sensor-based filter can be scored like any other
estimator's. ``earth_frame.EarthFrameTracker`` derives the pose in two ways, and each gets
its first-order covariance here, in world coordinates ``[dp (d), dphi (r)]``
(``p_true = p + dp``; 2-D ``theta_true = theta + dtheta``, 3-D ``R_true = Exp(dphi) R``;
the filter converts it to the interface's right perturbation at the boundary,
``filters.ekf_slam.boundary``). ``J v`` below is the derivative of a rotated vector ``v``
with respect to ``dphi`` (``rotation_lever``): 2-D ``[[0, -1], [1, 0]] v`` (d x 1), 3-D
``-[v]x`` (3 x 3).

- **Composition** ``p_k = p_{k-1} + R_{k-1} t``, ``R_k = R_{k-1} R_phi`` of an increment
  ``(t, phi)`` known to ``Q`` (body frame k-1): ``P_k = F P F^T + G Q G^T`` with
  ``F = [[I, J (R_{k-1} t)], [0, I]]``, ``G = diag(R_{k-1}, R_{k-1})`` (2-D: ``diag(R, 1)``).
  ``Q`` is the motion's uncertainty over the increment: with odometry, from the odometry's
  own per-sample covariance (the dataset's noise model, ``accumulate_odometry_covariance``);
  without, from the filter's velocity and bias uncertainty (``motion_covariance``). The
  increment aligns consecutive body-frame maps whose errors are mostly shared, so the
  landmarks' stated covariances would overstate it by far.
- **Anchoring**: the pose ``(R, p)`` minimising ``sum w_i |R s_i + p - y_i|^2`` over body-frame
  landmarks ``s_i`` and their Earth-map positions ``y_i``. Perturbing the normal equations
  (Gauss-Newton at the solution, ``H_i = [I, J (R s_i)]``, ``M = (sum w_i H_i^T H_i)^-1``)
  gives ``dx = sum_i A_i (dy_i - R ds_i)`` with ``A_i = w_i M H_i^T`` (``alignment_gains``):
  exact to first order for *any* weights, so the scalar weights of the alignment need not be
  the inverse covariances. The current body-frame landmarks ``ds`` enter with their *joint*
  covariance from the filter (the robocentric map's errors share the vehicle's motion
  error: treating them as independent would understate the pose error).
- **Entering a landmark** ``y = R s + p`` into the Earth map: ``dy = [I, J (y - p)] dx +
  R ds``, correlated with the pose error of that moment, and landmarks entered together
  with the joint error of their body-frame positions.

**3-D: built and tested here, not exported** (``earth_frame.EarthFrameTracker`` keeps the
3-D pose without a covariance). The algebra is the same with ``J v = -[v]x``, and the Monte
Carlo tests pass in 3-D; on the simulator, switched on, sensor-based's 3-D pose read NEES
per dof 1.19 on the calibration suite's circle (seeds 0-24, its settings; the suite's band
for that row is [0.65, 1.45]) but 1.74 on ``sim:aghili-rover`` (seeds 0-9, 10 s; the height
axis about 5x, tilt about 2x). Traced on seed 0 at 1 s: the first-order transfer reproduces
the anchored error exactly (0.232 against 0.232 m in height), the filter's own body-map term
is consistent (aligning its map to the true landmarks: 0.9-1.2 per axis over 5 seeds), and
the height error comes from the Earth entries, which project 3.5 standard deviations onto
height and tilt: a correlated error of the entries that the covariance does not hold. Until
that is understood a 3-D pose NEES would blame the filter for our approximation. A 3-D map
of landmarks whose height is not measured (lidar slab corners) would in any case fix only
heading and horizontal position (``earth_frame.horizontal_alignment``), its tilt and height
the filter's motion alone.

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
the operations they linearise, in 2-D and 3-D; ``tests/test_utias_sensor_based.py`` scores
the pose NEES on UTIAS.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag

from datasets.rotations import PLANAR_GENERATOR, skew


def rotation_lever(vectors: np.ndarray) -> np.ndarray:
    """``J v`` (n, d, r) for vectors (n, d): the change of a world-frame vector under a small
    world rotation ``dphi``; 2-D ``PLANAR_GENERATOR v`` (r = 1), 3-D ``-[v]x`` (r = 3)."""
    vectors = np.asarray(vectors, dtype=float)
    if vectors.shape[1] == 2:
        return (vectors @ PLANAR_GENERATOR.T)[:, :, None]
    return -np.stack([skew(vector) for vector in vectors])


def _rigid_lever(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(n, d, k): each point's displacement under a small world motion ``[dp, dphi]`` about
    its centre (d,) or (n, d): ``[I, J (point - centre)]``."""
    points = np.asarray(points, dtype=float)
    count, dimension = points.shape
    turn = rotation_lever(points - centres)
    return np.concatenate(
        [np.broadcast_to(np.eye(dimension), (count, dimension, dimension)), turn], 2
    )


def pose_dimension(dimension: int) -> int:
    """k: 3 for planar poses, 6 in 3-D."""
    return 3 if dimension == 2 else 6


def motion_covariance(
    velocity_gain: np.ndarray,
    duration_s: float,
    vehicle_covariance: np.ndarray,
    velocity_density: float | np.ndarray,
    bias_density: float,
    gyro_noise_density: float,
) -> np.ndarray:
    """Covariance (k, k) of the filter's dead-reckoned motion ``[t, phi]`` over one increment
    of ``duration_s`` (module docstring, composition).

    ``t = sum_j R_j v dt_j`` and ``phi = sum_j (omega_m - b) dt_j``: an error in the velocity
    estimate moves ``t`` by ``velocity_gain dv`` (``velocity_gain = sum_j R_j dt_j``), an
    error in the bias turns ``phi`` by ``-T db``; the random walks over the increment add
    ``sigma^2 T^3 / 3`` and the gyro's white noise ``sigma_g^2 T``.

    Args:
        velocity_gain: (d, d) ``sum_j R_j dt_j`` [s]; duration_s: T [s].
        vehicle_covariance: (d + r, d + r) covariance of the filter's ``[v, b]`` now.
        velocity_density: sigma_v [m/s/sqrt(s)], scalar or per body axis (d,).
        bias_density: sigma_b [rad/s/sqrt(s)]; gyro_noise_density: [rad/s/sqrt(Hz)].
    """
    dimension = len(velocity_gain)
    size = pose_dimension(dimension)
    jacobian = np.zeros((size, size))
    jacobian[:dimension, :dimension] = velocity_gain
    jacobian[dimension:, dimension:] = -duration_s * np.eye(size - dimension)
    result = jacobian @ vehicle_covariance @ jacobian.T
    cube = duration_s**3 / 3.0
    walk = np.broadcast_to(np.square(velocity_density), (dimension,)) * cube
    result[:dimension, :dimension] += np.diag(walk)
    turn = bias_density**2 * cube + gyro_noise_density**2 * duration_s
    result[dimension:, dimension:] += turn * np.eye(size - dimension)
    return 0.5 * (result + result.T)


def _composition_transition(size: int, rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """``F = [[I, J (R t)], [0, I]]`` (size, size) of a composition ``p += R t`` (module
    docstring, composition)."""
    transition = np.eye(size)
    transition[: len(rotation), len(rotation) :] = rotation_lever((rotation @ translation)[None])[0]
    return transition


def accumulate_odometry_covariance(
    accumulated: np.ndarray,
    rotation: np.ndarray,
    step: np.ndarray,
    dt: float,
    covariance: np.ndarray,
    relative_pose: bool,
) -> np.ndarray:
    """The covariance (3, 3) of the planar motion ``[t, phi]`` accumulated since the last scan
    (in that scan's body frame) after one more odometry sample: the composition above,
    ``F Q F^T + G Sigma G^T`` with the sample's own translation ``step`` (2,) [m] (its start
    frame) as the lever of the heading error so far. Planar only, as the pose covariance is
    exported (module docstring, 3-D).

    Args:
        accumulated: (3, 3) before the sample; rotation: (2, 2) the motion's rotation at the
            sample's start.
        covariance: the sample's own: a relative pose's ``[x, y, theta]`` (3, 3), or a
            velocity's ``[v_forward, omega]`` (2, 2) held for ``dt`` [s].
    """
    transition = _composition_transition(3, rotation, step)
    if relative_pose:
        gain = block_diag(rotation, 1.0)
    else:
        gain = np.zeros((3, 2))
        gain[:2, 0] = rotation[:, 0] * dt
        gain[2, 1] = dt
    return transition @ accumulated @ transition.T + gain @ covariance @ gain.T


def alignment_gains(
    rotation: np.ndarray, body_positions: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """``A_i`` (n, k, d) of an anchoring alignment (module docstring): the pose error
    ``[dp, dphi]`` is ``sum_i A_i (dy_i - R ds_i)``.

    Args:
        rotation: (d, d) the anchored body-to-Earth rotation ``R``.
        body_positions: (n, d) ``s_i`` [m]; weights: (n,) ``w_i`` (any positive scale).
    """
    design = _rigid_lever(body_positions @ rotation.T, np.zeros(len(rotation)))
    information = np.einsum("n,nki,nkj->ij", weights, design, design)
    return weights[:, None, None] * np.einsum("ij,nkj->nik", np.linalg.inv(information), design)


class EarthErrorCovariance:
    """Joint first-order covariance of the Earth pose's error ``[dp, dphi]`` (world
    coordinates) and of every Earth-map entry's position error (module docstring).

    Attributes:
        dimension: d; matrix: (k + d m, k + d m), the pose first, then the m entries in
            ``slots`` order; slots: entry key -> its index among the entries.
    """

    def __init__(self, dimension: int, pose_covariance: np.ndarray) -> None:
        self.dimension = dimension
        size = pose_dimension(dimension)
        self.matrix = np.array(pose_covariance, dtype=float).reshape(size, size)
        self.slots: dict[int, int] = {}

    @property
    def _pose_size(self) -> int:
        return pose_dimension(self.dimension)

    @property
    def pose(self) -> np.ndarray:
        """The pose error's covariance (k, k)."""
        size = self._pose_size
        return self.matrix[:size, :size].copy()

    def _rows(self, keys: list[int]) -> np.ndarray:
        first = self._pose_size
        return np.array(
            [
                first + self.dimension * self.slots[key] + axis
                for key in keys
                for axis in range(self.dimension)
            ]
        )

    def compose(
        self, rotation: np.ndarray, translation: np.ndarray, increment_covariance: np.ndarray
    ) -> None:
        """``p += R t``, ``R = R R_phi`` (module docstring, composition).

        Args:
            rotation: (d, d) the pose's rotation before; translation: (d,) the increment in
                that body frame [m]; increment_covariance: (k, k) of ``[t, phi]``.
        """
        size = self._pose_size
        transition = _composition_transition(size, rotation, translation)
        noise_gain = block_diag(rotation, rotation if self.dimension == 3 else 1.0)
        self.matrix[:size, :] = transition @ self.matrix[:size, :]
        self.matrix[:, :size] = self.matrix[:, :size] @ transition.T
        self.matrix[:size, :size] += noise_gain @ increment_covariance @ noise_gain.T
        self._symmetrise_pose()

    def enter(
        self,
        keys: list[int],
        earth_positions: np.ndarray,
        pose_position: np.ndarray,
        own_covariance: np.ndarray,
    ) -> None:
        """Add the entries ``y_i = R s_i + p`` made at one pose (module docstring, entering a
        landmark), with the joint error of their body-frame positions: the robocentric map's
        errors share the vehicle's, and taken one by one the entries made together would
        average it away (3-D rover, one run: the first anchor's height 3 standard deviations
        off).

        Args:
            keys: the n entries; earth_positions: (n, d) ``y_i`` [m]; pose_position: (d,)
                ``p`` now [m]; own_covariance: (n d, n d) the joint ``R C_s R^T`` of their
                body-frame positions in Earth axes.
        """
        size, dimension = self._pose_size, self.dimension
        lever = _rigid_lever(earth_positions, pose_position).reshape(-1, size)  # (n d, k)
        cross = lever @ self.matrix[:size, :]  # (n d, N)
        block = cross[:, :size] @ lever.T + own_covariance
        total, added = len(self.matrix), len(lever)
        grown = np.zeros((total + added, total + added))
        grown[:total, :total] = self.matrix
        grown[total:, :total] = cross
        grown[:total, total:] = cross.T
        grown[total:, total:] = 0.5 * (block + block.T)
        self.matrix = grown
        first = (total - size) // dimension
        for offset, key in enumerate(keys):
            self.slots[int(key)] = first + offset

    def anchor(
        self, keys: list[int], gains: np.ndarray, rotation: np.ndarray, body_joint: np.ndarray
    ) -> None:
        """Replace the pose error by an anchoring's ``sum_i A_i (dy_i - R ds_i)``.

        Args:
            keys: the n entries aligned; gains: (n, k, d) ``A_i`` (``alignment_gains``);
            rotation: (d, d) ``R``; body_joint: (n d, n d) joint covariance of the ``s_i``.
        """
        size = self._pose_size
        rows = self._rows(keys)
        transfer = gains.transpose(1, 0, 2).reshape(size, -1)  # acts on the entries' rows
        body_gain = (gains @ rotation).transpose(1, 0, 2).reshape(size, -1)
        cross = transfer @ self.matrix[rows, :]  # the new pose error with everything, (k, N)
        pose = cross[:, rows] @ transfer.T + body_gain @ body_joint @ body_gain.T
        self.matrix[:size, size:] = cross[:, size:]
        self.matrix[size:, :size] = cross[:, size:].T
        self.matrix[:size, :size] = pose
        self._symmetrise_pose()

    def forget(self, key: int) -> None:
        """Drop an entry's rows (the landmark left the Earth map)."""
        slot = self.slots.pop(int(key), None)
        if slot is None:
            return
        first = self._pose_size + self.dimension * slot
        keep = np.delete(np.arange(len(self.matrix)), np.arange(first, first + self.dimension))
        self.matrix = self.matrix[np.ix_(keep, keep)]
        self.slots = {k: s - 1 if s > slot else s for k, s in self.slots.items()}

    def _symmetrise_pose(self) -> None:
        """Only the pose block can drift from symmetry: every other change writes a row and
        its column from the same values."""
        size = self._pose_size
        self.matrix[:size, :size] = 0.5 * (self.matrix[:size, :size] + self.matrix[:size, :size].T)
