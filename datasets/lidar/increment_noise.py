"""KISS-ICP's increment covariance, fitted on the recording from the corners it re-observes.

KISS-ICP reports no covariance, and a constant one cannot follow the recording: on the
synthetic corridor bag KISS-ICP's forward increments are 3-8 cm short in its first frames
and drift 0.4 m in 40 frames, against a stated 2 cm per frame. What the recording shows is
the corners the front end re-observes (``corner_tracking.Reobservation``): a fixed corner's
world position, seen through KISS-ICP's poses in frames ``i`` and ``j``, moves by
the two detections' errors *and* by KISS-ICP's error between the two frames.

The model: each frame's increment error is white with variance ``q_rot`` [rad^2] on each
rotation axis and ``q_trans`` [m^2] on each translation axis. To first order a re-observed
corner ``c`` (world, horizontal) then moves by

    r = e_j - e_i + sum_{k=i+1..j} ( dpsi_k perp(c - p_{k-1}) + R_{k-1} dt_k )

(a yaw error of increment ``k`` swings everything after it about the vehicle's position
``p_{k-1}``; a translation error shifts it), so ``r ~ N(0, C + q_rot A + q_trans B)`` with
``C`` the two detections' covariance sum, ``A = sum perp perp^T`` and
``B = sum R_{k-1} R_{k-1}^T`` (horizontal blocks). The fit is the maximum likelihood of
``(q_rot, q_trans) >= 0`` over the pairs of the last ``WINDOW_FRAMES`` frames, by Newton
steps (the covariance is linear in ``q``), renewed every ``REFIT_FRAMES`` frames from the
previous fit.

What is stated, per component: the larger of the estimate and the stated default
(``KissIcpSettings``); the stated default until the window's pairs come from ``MIN_FRAMES``
frames (the warm-up). The fit raises the covariance where the recording shows KISS-ICP worse
than stated (the synthetic corridor bag: 68 mm per frame against 20 mm), and never lowers it:
lowering needs more evidence than a recording's re-observations give (next paragraph). On the
real KITTI clip the fit reads 0 rad and 0-7 mm per frame (as pairs arrive), below the stated
0.002 rad and 20 mm, so the stated default stands; the front end prints and records the fit
beside the sigma in use (``kiss_icp_fit_sigma_*``, ``kiss_icp_sigma_*``), so a user who
knows better can state it (``--data kiss.rotation_sigma_rad=...``).

Pairs of one track share its first sighting, and every pair spanning an increment shares its
error, so the likelihood is a composite one: the estimate is unbiased (simulated, known
noise: 0.91-1.00 of the truth over 60 recordings, ``tests/test_increment_noise.py``), but one
recording of 90 frames fits the variance only to about +-60 % (one standard deviation), and
the composite likelihood's own Fisher standard error understates that spread 6-10x. A yaw
fitted at zero is common: on both recordings above the re-observed corners are close enough
(median range 3.5 m on the bag, 11 m on the clip) that the translation term explains them.
Stating such a fit would have made the estimators overconfident in heading: on the corridor
bag, whose true per-frame yaw error is 0.87 mrad, a yaw stated at 0.1 mrad raised iSAM2's
pose NEES from 1.5 to 5.3 per dof (5 bags).

A constant yaw-rate error is not white noise, and this model does not see it:
``yaw_rate_disagreement`` fits one. On the clip the same pairs imply KISS-ICP turns
0.41 +- 0.10 deg/s slower than the corners say (jackknife over corners), -1.2 deg over
the clip; every estimator, weighing KISS-ICP's increments against the corners, ends 0.70 deg
from KISS-ICP in that direction. The disagreement is the corners', not KISS-ICP's: every
fifth frame registered directly to the first at full resolution by an ICP that shares only
the clouds with KISS-ICP agrees with KISS-ICP's heading to 0.08 deg or better, 0.016 deg at
the last frame (``benchmarks/kitti_clip_registration_check.py``). So on the clip the
estimators' 0.7 deg is an error taken from the corners. What points at the cause: the
corners' along-track residuals grow with the change of their azimuth between sightings
(0.24 cm per degree, correlation 0.52; a clockwise 10 Hz sweep at the clip's 6 m/s that is
not motion-compensated predicts 0.17), and taking the clouds as KITTI raw's uncompensated
sweeps (``scans:`` option ``point_times=azimuth``) leaves -0.18 +- 0.27 deg/s and every
estimator 0.16-0.25 deg from KISS-ICP. The clip's readme says its scans are
motion-compensated; they are not: a compensated sweep shows a range step where its first and
last points meet (0.61 m behind the car at the clip's speed, measured on the clip after a
synthetic compensation), and the clip's ground rings show none larger than 2.3 cm anywhere
round (``benchmarks/kitti_clip_sweep_seam.py``). The front end warns when clouds without
per-point times disagree with KISS-ICP like this (``LidarFrontEnd.heading_warning``). On the
corridor bag, where KISS-ICP's per-frame yaw errors against the truth have mixed signs
(0.05 deg RMS), it reads -0.057 +- 0.27 deg/s (``workbench simulate lidar-corridor`` with its
defaults; the pairs taken as independent had said +-0.016 on a bag like it).

Horizontal only: the corners' height is the slab's (``corners``), so roll, pitch and height
are not seen; they take the yaw's and the horizontal translation's variance. The fit runs
causally (the covariance of frame ``j``'s increment uses the pairs up to frame ``j``), so a
filter's input never depends on what comes after it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage

from datasets.lidar.corner_tracking import Reobservation

WINDOW_FRAMES = 100
"""Pairs whose current frame is at most this many frames old enter the fit (10 s at 10 Hz):
a bounded cost per frame, and a fit that follows the scene."""

MIN_FRAMES = 10
"""The fit is used once the window's pairs come from this many frames (1 s at 10 Hz)."""

REFIT_FRAMES = 5
"""The fit is renewed every this many frames (half a second at 10 Hz): a covariance that
lags the recording by that much, for a fifth of the cost of a fit per frame."""

CORNER_CLUSTER_M = 0.5
"""Re-observation pairs whose first sightings lie this close [m] are taken as one physical
corner by ``yaw_rate_disagreement``'s standard error. Two distinct corners this close are
taken as one, which errs toward a larger error; on the real clip 0.01 m gives 48
clusters and +-0.087 deg/s, 0.5 m 19 clusters and +-0.096."""


PoseOf = Callable[[int], np.ndarray]
"""Frame number -> that frame's (4, 4) body-to-world pose."""


def pair_features(pair: Reobservation, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """One re-observation as a row (12,): its frame, residual (2,) [m], and packed (xx, xy,
    yy) detection covariance ``C`` [m^2], rotation design ``A`` [m^2/rad^2] and translation
    design ``B`` (module docstring), from the horizontal ``positions`` (n, 2) [m] and
    rotation blocks ``rotations`` (n, 2, 2) of every frame up to ``pair.frame``."""
    first = pair.frame - pair.frames
    offsets = positions[pair.frame] + pair.lever - positions[first : pair.frame]
    ox, oy = offsets[:, 0], offsets[:, 1]
    # perp = (-oy, ox): A = sum perp perp^T
    rotation_design = [oy @ oy, -(ox @ oy), ox @ ox]
    blocks = rotations[first : pair.frame]
    translation = np.einsum("kab,kcb->ac", blocks, blocks)
    return np.array(
        [
            pair.frame,
            *pair.residual,
            pair.covariance[0, 0],
            pair.covariance[0, 1],
            pair.covariance[1, 1],
            *rotation_design,
            translation[0, 0],
            translation[0, 1],
            translation[1, 1],
        ],
        dtype=float,
    )


@dataclass(frozen=True)
class IncrementNoise:
    """The per-frame variances in use and where they come from.

    Attributes:
        rotation_variance: [rad^2] on each rotation axis of one increment.
        translation_variance: [m^2] on each translation axis.
        source: ``stated`` or ``re-observations (N pairs)``.
        estimate: the fit's (rotation, translation) [rad^2, m^2], or None.
    """

    rotation_variance: float
    translation_variance: float
    source: str
    estimate: tuple[float, float] | None = None

    def covariance(self) -> np.ndarray:
        """(6, 6) covariance of an increment ``(rotation vector, translation)``."""
        return np.diag([self.rotation_variance] * 3 + [self.translation_variance] * 3)

    def summary(self) -> dict[str, float | str | None]:
        """For the front end's metrics: sigmas and the fit behind them."""
        return {
            "kiss_icp_sigma_rotation_rad": float(np.sqrt(self.rotation_variance)),
            "kiss_icp_sigma_translation_m": float(np.sqrt(self.translation_variance)),
            "kiss_icp_covariance_source": self.source,
            "kiss_icp_fit_sigma_rotation_rad": None
            if self.estimate is None
            else float(np.sqrt(self.estimate[0])),
            "kiss_icp_fit_sigma_translation_m": None
            if self.estimate is None
            else float(np.sqrt(self.estimate[1])),
        }


class IncrementNoiseFit:
    """Collects re-observations frame by frame and states each increment's covariance
    (module docstring)."""

    def __init__(self, stated_rotation_sigma_rad: float, stated_translation_sigma_m: float):
        self.stated = IncrementNoise(
            stated_rotation_sigma_rad**2, stated_translation_sigma_m**2, "stated"
        )
        self.current = self.stated
        self._rows = np.zeros((0, 12))  # pair_features rows of the window
        self._estimate: np.ndarray | None = None
        self._positions = np.zeros((64, 2))  # every frame's, grown by doubling
        self._rotations = np.zeros((64, 2, 2))
        self._frames = 0  # frames stored
        self._fitted_at = -REFIT_FRAMES  # frame of the last fit

    def update(self, frame: int, pairs: list[Reobservation], pose_of: PoseOf) -> None:
        """Add the re-observations made at ``frame`` and refit every ``REFIT_FRAMES``
        frames (``pose_of`` gives the poses of frames up to ``frame``)."""
        self._store_poses(frame, pose_of)
        if pairs:
            new = np.array(
                [pair_features(pair, self._positions, self._rotations) for pair in pairs]
            )
            self._rows = np.concatenate([self._rows, new])
        self._rows = self._rows[self._rows[:, 0] > frame - WINDOW_FRAMES]
        if frame - self._fitted_at < REFIT_FRAMES or len(self._rows) == 0:
            return
        if len(np.unique(self._rows[:, 0])) < MIN_FRAMES:
            return
        fitted = fit_increment_variances(self._rows, self._estimate)
        self._fitted_at = frame
        if fitted is None:
            return
        self._estimate = fitted
        stated = np.maximum(
            self._estimate, [self.stated.rotation_variance, self.stated.translation_variance]
        )
        self.current = IncrementNoise(
            float(stated[0]),
            float(stated[1]),
            f"re-observations ({len(self._rows)} pairs)",
            (float(self._estimate[0]), float(self._estimate[1])),
        )

    def _store_poses(self, frame: int, pose_of: PoseOf) -> None:
        """Keep the horizontal position and rotation block of frames up to ``frame``."""
        if frame >= len(self._positions):
            grown = max(2 * len(self._positions), frame + 1)
            self._positions = np.resize(self._positions, (grown, 2))
            self._rotations = np.resize(self._rotations, (grown, 2, 2))
        for k in range(self._frames, frame + 1):
            pose = pose_of(k)
            self._positions[k] = pose[:2, 3]
            self._rotations[k] = pose[:2, :2]
        self._frames = max(self._frames, frame + 1)


def fit_increment_variances(
    rows: np.ndarray, start: np.ndarray | None = None, iterations: int = 30
) -> np.ndarray | None:
    """Maximum likelihood ``(q_rot, q_trans) >= 0`` of ``r ~ N(0, C + q_rot A + q_trans B)``
    over the ``pair_features`` rows (n, 12), by Newton steps with an active set; None when
    the curvature is singular (pairs that cannot tell the two apart)."""
    residuals, base = rows[:, 1:3], rows[:, 3:6]
    designs = (rows[:, 6:9], rows[:, 9:12])
    # variances at which each design adds about as much as the detections: the first start,
    # and the scale of the convergence test
    scale = np.array([_trace(base).mean() / max(_trace(d).mean(), 1e-12) for d in designs])
    q = 0.1 * scale if start is None else np.array(start, dtype=float)
    for _ in range(iterations):
        gradient, information, observed = _score(residuals, base, designs, q)
        # Newton on the observed information where it is positive definite (quadratic
        # convergence; Fisher scoring alone oscillates here when the model misfits), else a
        # scoring step
        curvature = observed if np.all(np.linalg.eigvalsh(observed) > 0.0) else information
        # active set: a variance at zero whose likelihood still falls towards zero stays
        # there, and the step is taken in the other alone (a full step would zig-zag)
        free = ~((q <= 0.0) & (gradient <= 0.0))
        step = np.zeros(2)
        try:
            step[free] = np.linalg.solve(curvature[np.ix_(free, free)], gradient[free])
        except np.linalg.LinAlgError:
            return None
        updated = np.maximum(q + step, 0.0)
        converged = np.all(np.abs(updated - q) <= 1e-3 * np.abs(updated) + 1e-9 * scale)
        q = updated
        if converged:
            break
    return q


def _trace(packed: np.ndarray) -> np.ndarray:
    return packed[..., 0] + packed[..., 2]


def _score(
    residuals: np.ndarray, base: np.ndarray, designs: tuple[np.ndarray, np.ndarray], q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gradient of the log-likelihood in ``q`` (2,), the Fisher (expected) information and
    the observed information (2, 2):

        g_x = 1/2 sum (u^T D_x u - tr(S^-1 D_x)),  F_xy = 1/2 sum tr(S^-1 D_x S^-1 D_y),
        J_xy = sum u^T D_x S^-1 D_y u - F_xy

    with ``S = C + q_0 A + q_1 B``, ``u = S^-1 r``; every pair's 2x2 matrices packed (xx,
    xy, yy) and inverted in closed form."""
    covariance = base + q[0] * designs[0] + q[1] * designs[1]
    xx, xy, yy = covariance[:, 0], covariance[:, 1], covariance[:, 2]
    determinant = xx * yy - xy * xy
    ixx, ixy, iyy = yy / determinant, -xy / determinant, xx / determinant
    ux = ixx * residuals[:, 0] + ixy * residuals[:, 1]
    uy = ixy * residuals[:, 0] + iyy * residuals[:, 1]
    products = []  # S^-1 D as its four entries
    pushed = []  # D u
    gradient = np.empty(2)
    for index, design in enumerate(designs):
        dxx, dxy, dyy = design[:, 0], design[:, 1], design[:, 2]
        pushed.append((dxx * ux + dxy * uy, dxy * ux + dyy * uy))
        products.append(
            (
                ixx * dxx + ixy * dxy,
                ixx * dxy + ixy * dyy,
                ixy * dxx + iyy * dxy,
                ixy * dxy + iyy * dyy,
            )
        )
        quadratic = dxx * ux * ux + 2.0 * dxy * ux * uy + dyy * uy * uy
        gradient[index] = 0.5 * np.sum(quadratic - (products[-1][0] + products[-1][3]))
    information, observed = np.empty((2, 2)), np.empty((2, 2))
    for a, (l00, l01, l10, l11) in enumerate(products):
        for b, (r00, r01, r10, r11) in enumerate(products):
            information[a, b] = 0.5 * np.sum(l00 * r00 + l01 * r10 + l10 * r01 + l11 * r11)
            (vx, vy), (wx, wy) = pushed[a], pushed[b]
            quadratic = ixx * vx * wx + ixy * (vx * wy + vy * wx) + iyy * vy * wy
            observed[a, b] = np.sum(quadratic) - information[a, b]
    return gradient, information, observed


def yaw_rate_disagreement(
    pairs: list[Reobservation], positions: np.ndarray, rotations: np.ndarray, times: np.ndarray
) -> tuple[float, float] | None:
    """The constant yaw-rate error [rad/s] of the poses that the re-observations imply, and
    its standard error, or None when the pairs cannot determine it.

    If the poses' heading drifts at ``omega`` and their velocity is off by a constant ``u``
    (body frame, [m/s]), a corner seen in frames ``i`` and ``j`` moves by
    ``sum_{k=i+1..j} dt_k (omega perp(c - p_{k-1}) + R_{k-1} u)`` (module docstring, with
    the errors ``omega dt_k`` and ``u dt_k`` on each increment); weighted least squares of
    ``(omega, u)`` over the pairs with their detection covariances. The velocity term is
    there because a forward drift moves the corners beside the path along it, which a yaw
    drift alone would take for a turn (the corridor bag: -0.96 deg/s without it).
    Positive: the poses turn more (counter-clockwise) than the corners say.

    The standard error is the delete-one-corner jackknife (``sqrt((G - 1) / G
    sum_g (omega_-g - mean)^2)`` over ``G`` corners): every pair of one physical corner
    shares its first sighting and its detection errors, so the pairs are not independent,
    and with a few tens of corners the cluster sandwich is itself optimistic. A corner is
    the pairs whose first sightings lie within ``CORNER_CLUSTER_M`` of each other (single
    linkage), so that a corner whose track the tracker restarted counts once. On the real
    KITTI clip (19 corners): pairs taken as independent +-0.065 deg/s, cluster sandwich
    +-0.074, this jackknife +-0.096, a bootstrap over the corners +-0.14. None with fewer
    than three corners, or when leaving one out leaves the fit undetermined.

    Args:
        pairs: the tracker's re-observations. positions: (n, 2) horizontal position of every
            frame [m]. rotations: (n, 2, 2) horizontal rotation block of every frame.
            times: (n,) pose time of every frame [s].
    """
    if not pairs:
        return None
    designs, weights, residuals, firsts = [], [], [], []
    for pair in pairs:
        first = pair.frame - pair.frames
        offsets = positions[pair.frame] + pair.lever - positions[first : pair.frame]
        steps = np.diff(times[first : pair.frame + 1])
        design = np.empty((2, 3))
        design[:, 0] = steps @ np.column_stack([-offsets[:, 1], offsets[:, 0]])
        design[:, 1:] = np.einsum("k,kab->ab", steps, rotations[first : pair.frame])
        designs.append(design)
        weights.append(np.linalg.inv(pair.covariance))
        residuals.append(pair.residual)
        firsts.append(positions[pair.frame] + pair.lever - pair.residual)
    design, weight, residual = np.array(designs), np.array(weights), np.array(residuals)
    weighted = np.einsum("kji,kjl->kil", design, weight)  # A^T W, (k, 3, 2)
    pair_information = np.einsum("kij,kjl->kil", weighted, design)  # A^T W A, (k, 3, 3)
    pair_projection = np.einsum("kij,kj->ki", weighted, residual)  # A^T W r, (k, 3)
    information = pair_information.sum(axis=0)
    if not np.all(np.isfinite(information)) or np.linalg.matrix_rank(information) < 3:
        return None
    clusters = fcluster(linkage(np.array(firsts), "single"), CORNER_CLUSTER_M, "distance") - 1
    count = int(clusters.max()) + 1
    if count < 3:
        return None
    projection = pair_projection.sum(axis=0)
    estimate = np.linalg.solve(information, projection)
    cluster_information = np.zeros((count, 3, 3))
    np.add.at(cluster_information, clusters, pair_information)
    cluster_projection = np.zeros((count, 3))
    np.add.at(cluster_projection, clusters, pair_projection)
    left_information = information - cluster_information
    if np.any(np.linalg.matrix_rank(left_information) < 3):
        return None
    left_out = np.linalg.solve(left_information, (projection - cluster_projection)[..., None])
    omegas = left_out[:, 0, 0]
    spread = (count - 1) / count * np.sum((omegas - omegas.mean()) ** 2)
    return float(estimate[0]), float(np.sqrt(spread))
