"""An estimate against the lidar front end's own trajectory (``Sequence.front_end``): how far
it ends from it, and whether it leaves it by more than their stated covariances allow.

On a lidar recording without truth the front end's trajectory (KISS-ICP's) is the one
reference there is, and a landmark estimator that bends away from it by a degree over 50 m
while its NIS looks fine shows nowhere else (issue 37).

**Alignment: at the start, not Umeyama.** The estimate is moved into the front end's world
by the one transform that puts the sequence's initial state (where every estimator starts,
with its stated prior) on the front end's first pose (the same instant: the loaders start
the sequence at the front end's first pose); without an initial state at that time, by the
transform that puts the first paired estimate pose on the front end's. Both trajectories
start from the same pose by construction, so nothing is left to fit; a least-squares
(Umeyama) alignment would rotate the estimate to spread a heading departure over the whole
path and halve the deviation this measures.

**Agreement** (``frontend_*`` keys of metrics.json): over the estimate's poses paired with
the front end's frames (nearest stamp within ``PAIR_TOLERANCE_S``), the largest position
distance after the alignment [m] and as a percentage of the front end's path length, and
the yaw of ``R_fe^T R_est`` at the last paired frame [deg] (estimate minus front end: the
z component of the body-frame rotation vector in 3-D, the heading difference in 2-D).

**Departure check.** At each paired frame the relative pose
``d = log(T_fe^-1 T_est)`` (after the alignment: equal to the difference of the two relative
poses since the start) is tested on its yaw and horizontal position (3 dof; roll, pitch and
height are left out: the corners, horizontal, do not inform them, so an estimator follows
the increments there and the difference's covariance vanishes) with the statistic
``s = d^T C^-1 d`` against a chi-square bound. ``C``, the covariance of the difference,
is ``P_est + P_fe - X - X^T`` with ``X`` the cross covariance of the two errors; the two
are correlated because the estimators consume the front end's increments. What is taken:

- ``P_fe``: the front end's pose covariance, accumulated from the covariance of each
  increment it fed the estimators (``FrontEndReport.increment_covariances``; right
  perturbations, ``P_k = Ad(U_k^-1) P_{k-1} Ad(U_k^-1)^T + Q_k``) from the sequence's stated
  initial prior, the same prior the estimators start with.
- Where the front end's increments are the sequence's only motion input
  (``FrontEndReport.sole_motion_input``: no IMU, gyro or wheel odometry) every estimator
  fuses them with the corners, which are independent of them. An efficient, consistent
  fusion's error is uncorrelated with its difference from a less informed consistent
  estimate of the same pose (Hausman, Econometrica 46(6), 1978: the covariance of the
  difference of an efficient and an inefficient estimator is the difference of their
  covariances), so ``X = P_est`` and ``C = P_fe - P_est``. Where the estimate states no
  pose covariance (the sensor-based filter in 3-D) ``C = P_fe``, which bounds
  ``P_fe - P_est`` from above: a test that fires less often, never more.
- Otherwise (a lidar + IMU bag: an estimator may move by the IMU and share only the clouds
  with the front end) ``X`` is taken as zero, ``C = P_est + P_fe``, which bounds every
  non-negative correlation from above; without ``P_est`` there the check does not run.
- The statistic's resolution is one increment: the covariance ``Q_k`` of the frame's own
  increment is added to ``C`` (``P_fe - P_est`` has its negative eigenvalues, which an
  estimator that is not exactly efficient gives, clipped to zero first, in the frame
  whitened by ``Q_k``). The two start at the same pose with the same prior, so at the first
  frames ``P_fe - P_est`` is zero and an estimator that has not yet moved away from the
  increments by one increment's error is never a departure.

**False-alarm rate.** ``FALSE_ALARM_RATE`` per run (1e-4): the bound at every frame is the
chi-square (3 dof) quantile at ``1 - FALSE_ALARM_RATE / N`` for ``N`` frames compared
(Bonferroni over the frames, conservative for the strongly correlated statistics of
consecutive frames). The first frame over the bound is the departure: its time, its size
(yaw [deg], position [m]), the statistic and the bound go into metrics.json and one warning
line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from datasets.estimate import Estimate
from datasets.lidar.frontend_report import FrontEndReport
from datasets.rotations import matrix_from_quat_wxyz, rot2, so3_log, wrap_angle
from datasets.sequence import InitialState, Sequence
from datasets.trajectory import Trajectory

FALSE_ALARM_RATE = 1e-4
"""Probability per run that the departure check fires on an estimate that agrees with the
front end within their stated covariances (Bonferroni over the frames compared)."""

PAIR_TOLERANCE_S = 0.01
"""An estimate pose within this of a front-end frame [s] is that frame's (evo's pairing)."""

TESTED_DOF = 3
"""Yaw and horizontal position (module docstring)."""

KEYS = (
    "frontend_name",
    "frontend_frames",
    "frontend_ate_rmse_m",
    "frontend_ms_per_frame",
    "frontend_reobservation_nis_per_dof",
    "frontend_path_length_m",
    "frontend_frames_compared",
    "frontend_max_deviation_m",
    "frontend_max_deviation_percent_path",
    "frontend_final_yaw_diff_deg",
    "frontend_departure_covariance",
    "frontend_departure_max_nees",
    "frontend_departure_max_nees_t_s",
    "frontend_departure_bound",
    "frontend_departure_false_alarm_rate",
    "frontend_departure_t_s",
    "frontend_departure_nees",
    "frontend_departure_yaw_deg",
    "frontend_departure_position_m",
)
"""Every key ``frontend_metrics`` writes (all None without a front end)."""


@dataclass(frozen=True)
class FrontEndComparison:
    """An estimate against the front end at their paired frames (module docstring).

    Attributes:
        t: the paired frames' times [s], (N,).
        difference: ``d`` as [yaw [rad], x [m], y [m]] in the front end's body frame, (N, 3).
        distance_m: position distance after the alignment [m], (N,).
        statistic: ``d^T C^-1 d`` per frame, (N,), or None when not tested.
        covariance_rule: which ``C`` was used (module docstring), or why none was.
        path_length_m: the front end's path length over all its frames [m].
    """

    t: np.ndarray
    difference: np.ndarray
    distance_m: np.ndarray
    statistic: np.ndarray | None
    covariance_rule: str
    path_length_m: float

    @property
    def bound(self) -> float:
        """The chi-square bound every frame's statistic is held to (module docstring)."""
        return float(chi2.ppf(1.0 - FALSE_ALARM_RATE / max(len(self.t), 1), TESTED_DOF))

    def departure(self) -> int | None:
        """Index of the first frame whose statistic exceeds the bound, or None."""
        if self.statistic is None:
            return None
        over = np.flatnonzero(self.statistic > self.bound)
        return int(over[0]) if over.size else None


def _homogeneous(trajectory: Trajectory) -> np.ndarray:
    return trajectory.homogeneous()


def _initial_pose(state: InitialState, dimension: int) -> np.ndarray:
    pose = np.eye(dimension + 1)
    if dimension == 3:
        pose[:3, :3] = matrix_from_quat_wxyz(np.asarray(state.rotation, dtype=float))
    else:
        pose[:2, :2] = rot2(float(state.rotation))
    pose[:dimension, dimension] = np.asarray(state.position, dtype=float)[:dimension]
    return pose


def _inverse_adjoint(increment: np.ndarray) -> np.ndarray:
    """``Ad(U^-1)`` of a (d+1, d+1) increment in the interface's tangent order: 3-D
    [rotation, translation] (GTSAM Pose3), 2-D [x, y, theta] (GTSAM Pose2)."""
    dimension = increment.shape[0] - 1
    rotation, translation = increment[:dimension, :dimension], increment[:dimension, dimension]
    if dimension == 3:
        from datasets.rotations import pose3_inverse_adjoint

        return pose3_inverse_adjoint(so3_log(rotation), translation)
    adjoint = np.eye(3)  # Pose2 Ad(U) = [[R, (y, -x)], [0, 1]]
    adjoint[:2, :2] = rotation
    adjoint[:2, 2] = (translation[1], -translation[0])
    return np.linalg.inv(adjoint)


def _selection(dimension: int) -> list[int]:
    """Indices of [yaw, x, y] in a pose covariance of the interface's order."""
    return [2, 3, 4] if dimension == 3 else [2, 0, 1]


def accumulated_covariances(report: FrontEndReport, initial: InitialState | None) -> np.ndarray:
    """The front end's pose covariance at each of its frames, (F, k, k): the initial
    state's stated prior (zero without one) carried through every increment with its stated
    covariance (module docstring). An increment without a covariance adds none."""
    poses = np.array(report.poses)
    dimension = poses.shape[1] - 1
    size = 6 if dimension == 3 else 3
    prior = np.zeros((size, size))
    if initial is not None:
        rotation, position = initial.rotation_sigma_rad**2, initial.position_sigma_m**2
        prior = np.diag(
            [rotation] * 3 + [position] * 3 if dimension == 3 else [position] * 2 + [rotation]
        )
    found = [prior]
    for k in range(1, len(poses)):
        adjoint = _inverse_adjoint(np.linalg.inv(poses[k - 1]) @ poses[k])
        step = report.increment_covariances[k]
        found.append(adjoint @ found[-1] @ adjoint.T + (0.0 if step is None else step))
    return np.array(found)


def _increment_floor(report: FrontEndReport, index: int, size: int) -> np.ndarray:
    """The covariance of the increment ending at frame ``index`` (the next one's for the
    first frame; the identity scaled to zero when there is none)."""
    steps = report.increment_covariances
    for candidate in (index, index + 1, index - 1):
        if 0 <= candidate < len(steps) and steps[candidate] is not None:
            return np.asarray(steps[candidate], dtype=float)
    return np.zeros((size, size))


def _difference_covariance(
    fe: np.ndarray, est: np.ndarray | None, floor: np.ndarray, shared: bool
) -> np.ndarray | None:
    """``C`` on [yaw, x, y] (module docstring): ``fe``, ``est`` and ``floor`` (3, 3)."""
    if est is None:
        return fe + floor if shared else None
    if not shared:
        return fe + est + floor
    try:
        lower = np.linalg.cholesky(floor)
    except np.linalg.LinAlgError:
        return None
    whitened = np.linalg.solve(lower, np.linalg.solve(lower, fe - est).T)
    values, vectors = np.linalg.eigh(0.5 * (whitened + whitened.T))
    clipped = (vectors * np.maximum(values, 0.0)) @ vectors.T + np.eye(3)
    return lower @ clipped @ lower.T


def compare_with_front_end(
    pose: Trajectory, report: FrontEndReport, initial: InitialState | None
) -> FrontEndComparison | None:
    """``pose`` against the front end's trajectory (module docstring), or None when no pose
    pairs with a front-end frame (or the two differ in dimension)."""
    reference = report.trajectory()
    if reference is None or len(pose) == 0 or pose.dimension != reference.dimension:
        return None
    dimension = pose.dimension
    front = _homogeneous(reference)
    estimate = _homogeneous(pose)
    nearest = np.clip(np.searchsorted(reference.t, pose.t), 0, len(reference) - 1)
    before = np.clip(nearest - 1, 0, len(reference) - 1)
    closer = np.abs(reference.t[before] - pose.t) < np.abs(reference.t[nearest] - pose.t)
    index = np.where(closer, before, nearest)
    paired = np.flatnonzero(np.abs(reference.t[index] - pose.t) <= PAIR_TOLERANCE_S)
    # one estimate pose per frame: the first at each
    paired = paired[np.unique(index[paired], return_index=True)[1]]
    if paired.size == 0:
        return None
    if initial is not None and abs(initial.t - reference.t[0]) <= PAIR_TOLERANCE_S:
        alignment = front[0] @ np.linalg.inv(_initial_pose(initial, dimension))
    else:
        first = paired[0]
        alignment = front[index[first]] @ np.linalg.inv(estimate[first])
    accumulated = accumulated_covariances(report, initial)
    select = _selection(dimension)
    rows, distances, statistics = [], [], []
    tested = pose.covariances is not None or report.sole_motion_input
    rule = _rule(pose.covariances is not None, report.sole_motion_input)
    for i in paired:
        k = int(index[i])
        moved = alignment @ estimate[i]
        rotation_fe = front[k][:dimension, :dimension]
        offset = rotation_fe.T @ (moved[:dimension, dimension] - front[k][:dimension, dimension])
        relative = rotation_fe.T @ moved[:dimension, :dimension]
        if dimension == 3:
            yaw = float(so3_log(relative)[2])
        else:
            yaw = float(wrap_angle(np.arctan2(relative[1, 0], relative[0, 0])))
        d = np.array([yaw, offset[0], offset[1]])
        rows.append(d)
        distances.append(float(np.linalg.norm(offset)))
        if not tested:
            continue
        fe = accumulated[k][np.ix_(select, select)]
        est = None if pose.covariances is None else pose.covariances[i][np.ix_(select, select)]
        floor = _increment_floor(report, k, accumulated.shape[1])[np.ix_(select, select)]
        covariance = _difference_covariance(fe, est, floor, report.sole_motion_input)
        if covariance is None or not np.all(np.isfinite(covariance)):
            statistics.append(np.nan)
            continue
        try:
            statistics.append(float(d @ np.linalg.solve(covariance, d)))
        except np.linalg.LinAlgError:
            statistics.append(np.nan)
    steps = np.diff(np.array(reference.positions), axis=0)
    return FrontEndComparison(
        t=pose.t[paired].astype(float),
        difference=np.array(rows),
        distance_m=np.array(distances),
        statistic=np.array(statistics) if tested else None,
        covariance_rule=rule,
        path_length_m=float(np.sum(np.linalg.norm(steps, axis=1))),
    )


def _rule(has_covariance: bool, shared: bool) -> str:
    if shared:
        return (
            "front end minus estimate (it fuses the front end's increments)"
            if has_covariance
            else "front end only (the estimate states no pose covariance; bounds front end "
            "minus estimate)"
        )
    if has_covariance:
        return "front end plus estimate (other motion input: no correlation taken)"
    return "not tested: other motion input and no pose covariance in the estimate"


def _scored_pose(estimate: Estimate) -> Trajectory | None:
    """The history metrics score: the causal one, else the smoothed one."""
    history = estimate.causal if estimate.causal.pose is not None else estimate.smoothed
    return None if history is None else history.pose


def _number(value) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def frontend_metrics(estimate: Estimate, sequence: Sequence) -> dict[str, object]:
    """The ``frontend_*`` keys of metrics.json (``KEYS``; module docstring), None where
    there is no front end (or nothing of the estimate pairs with its frames)."""
    metrics: dict[str, object] = dict.fromkeys(KEYS)
    report = sequence.front_end
    if report is None or report.frames == 0:
        return metrics
    metrics["frontend_name"] = report.name
    metrics["frontend_frames"] = int(report.frames)
    metrics["frontend_ms_per_frame"] = _number(report.ms_per_frame())
    metrics["frontend_reobservation_nis_per_dof"] = _number(report.reobservation_nis_per_dof())
    trajectory = report.trajectory()
    if trajectory is None:
        return metrics
    metrics["frontend_ate_rmse_m"] = _front_end_ate(trajectory, sequence)
    pose = _scored_pose(estimate)
    found = None if pose is None else compare_with_front_end(pose, report, sequence.initial_state)
    if found is None:
        return metrics
    path = found.path_length_m
    largest = float(np.max(found.distance_m))
    metrics.update(
        {
            "frontend_path_length_m": path,
            "frontend_frames_compared": int(len(found.t)),
            "frontend_max_deviation_m": largest,
            "frontend_max_deviation_percent_path": 100.0 * largest / path if path > 0 else None,
            "frontend_final_yaw_diff_deg": float(np.rad2deg(found.difference[-1, 0])),
            "frontend_departure_covariance": found.covariance_rule,
        }
    )
    if found.statistic is None or not np.any(np.isfinite(found.statistic)):
        return metrics
    worst = int(np.nanargmax(found.statistic))
    metrics.update(
        {
            "frontend_departure_max_nees": float(found.statistic[worst]),
            "frontend_departure_max_nees_t_s": float(found.t[worst]),
            "frontend_departure_bound": found.bound,
            "frontend_departure_false_alarm_rate": FALSE_ALARM_RATE,
        }
    )
    first = found.departure()
    if first is not None:
        metrics.update(
            {
                "frontend_departure_t_s": float(found.t[first]),
                "frontend_departure_nees": float(found.statistic[first]),
                "frontend_departure_yaw_deg": float(np.rad2deg(found.difference[first, 0])),
                "frontend_departure_position_m": float(found.distance_m[first]),
            }
        )
    return metrics


def _front_end_ate(trajectory: Trajectory, sequence: Sequence) -> float | None:
    """The front end's own ATE against the sequence's truth (scored as every estimate is:
    ``metrics.summary.scored_pairs``), None without truth."""
    from workbench.metrics.summary import scored_pairs

    found = scored_pairs(trajectory, sequence.ground_truth)
    if found is None:
        return None
    return _number(float(np.sqrt(np.mean(found.ate**2))))


def departure_warning(metrics: dict, estimator: str, dataset: str) -> list[str]:
    """One line when the departure check fired (``frontend_departure_t_s`` set): the
    estimator, the time of the first departure, its size and the statistic with its bound."""
    if metrics.get("frontend_departure_t_s") is None:
        return []
    name = metrics.get("frontend_name") or "front end"
    return [
        f"{estimator} on {dataset} leaves the front end's ({name}) trajectory at "
        f"t={metrics['frontend_departure_t_s']:.2f} s by "
        f"{metrics['frontend_departure_position_m']:.3f} m and "
        f"{metrics['frontend_departure_yaw_deg']:+.2f} deg in yaw: chi-square "
        f"{metrics['frontend_departure_nees']:.1f} > {metrics['frontend_departure_bound']:.1f} "
        f"(3 dof, false-alarm rate {FALSE_ALARM_RATE:g} per run; covariance: "
        f"{metrics['frontend_departure_covariance']})"
    ]
