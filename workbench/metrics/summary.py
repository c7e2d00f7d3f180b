"""``compute_metrics``: the flat ``metrics.json`` dictionary of one run.

Every key carries its unit where it has one; a value is None (JSON null) where it is not
defined (no ground truth, no covariance, no smoothed history, no world pose, ...). Values
are plain Python floats and ints, so ``json.dumps`` takes the dictionary as it is.

Keys (``_smoothed`` copies, placed before the unit, are computed on ``Estimate.smoothed``
and are None for filters):

accuracy (causal pose against ``GroundTruth.pose``; pairs by evo's nearest-stamp
association within 0.01 s, so the numbers equal ``workbench metrics`` on the run's TUM
files):
    ``ate_rmse_m`` (SE(3) alignment for 3-D poses, SE(2) for planar; a static or straight
    trajectory is aligned with one of the equally good minimisers), ``ate_rmse_raw_m`` (no
    alignment), ``rpe_trans_rmse_m`` and ``rpe_rot_rmse_deg`` (1-frame RPE),
    ``final_orientation_error_deg`` (Aghili eq. (43) at the last pose the truth covers),
    ``kitti_translation_percent`` and ``kitti_rotation_deg_per_100m`` (KITTI segments of
    100..800 m from every 10th paired pose, None on paths shorter than 100 m),
    ``gps_holdout_rmse_m`` (estimated positions interpolated linearly at
    ``GroundTruth.held_out_positions`` stamps inside the estimate's span, no alignment).
    Truth inside ``GroundTruth.excluded`` scores nothing: its samples leave the reference
    before pairing, estimate poses inside an interval leave the pairs, RPE pairs whose
    interval meets one are dropped (KITTI segments, 100 m and longer, keep their trusted
    ends), held-out fixes inside one are not compared.
relations (``relations_metrics``, Kümmerle et al. 2009: the estimate's relative poses against
``GroundTruth.relations``, given with ``--data relations=FILE``; ``workbench.metrics.relations``):
    ``relations_trans_error_mean_m``, ``relations_trans_error_std_m``,
    ``relations_rot_error_mean_deg``, ``relations_rot_error_std_deg`` (sample std, None for
    fewer than two), ``relations_trans_error_sq_mean_m2``, ``relations_rot_error_sq_mean_deg2``
    (means of the squares), ``relations_used``, ``relations_skipped`` and
    ``relations_skipped_reasons`` (``"N reason, ..."``, None when none was skipped), and the
    stamp tolerance ``relations_max_diff_s``. All None without relations (or without a pose
    history); ``_smoothed`` copies as above, except the tolerance.
consistency (``state_errors.nees_series``: truth looked up at the estimate's times):
    every NEES per degree of freedom (the sum of a block's NEES over the steps it is scored
    on, over the sum of their dof: 1 when consistent): ``nees_pose_per_dof`` (a pose has 6
    or 3 dof), ``nees_pose_inside_fraction`` (single-run NEES inside
    its two-sided 95% chi-square interval), ``nees_attitude_per_dof``, ``nees_position_per_dof``,
    ``nees_velocity_per_dof``, ``nees_gyro_bias_per_dof``, ``nees_accel_bias_per_dof``,
    ``nees_landmarks_per_dof`` (per landmark and snapshot, d dof; the final map when no
    snapshot was recorded). NaN values (singular covariances) are left out.
innovations: ``nis_per_dof`` (every update's stacked NIS summed over the summed dof: the
    figure comparable across estimators), ``nis_update_inside_fraction`` (updates inside
    their two-sided 95% band); per associated measurement ``nis_measurement_per_dof``, ``nis_dof`` (None
    when dofs differ), ``nis_inside_fraction`` (two-sided 95% per dof),
    ``nis_below_95_fraction`` (one-sided, Guerreiro eq. (11)).
map (``Estimate.landmarks`` against ``GroundTruth.landmarks``; estimator ids mapped to true
ids by ``data_association.landmark_id_mapping``: majority true id of the association
records, else the same id): ``landmark_rmse_m``, ``landmarks_mapped`` (landmarks matched to a
    true one; None without a true map); ``landmarks_in_map`` (every landmark of the final
    map, with or without truth: a recording without truth still says how big its map is).
association: ``association_rejected_fraction``, ``association_ambiguous_fraction`` (of all
    sightings: not used), ``association_inflated_fraction`` (used with inflated noise: a
    known id outside the id gate, or a geometric pairing by mutual exclusion between the
    association and new-landmark gates, ``filters.association.policy``),
    ``association_contested_fraction`` (of the sightings decided geometrically by one
    hypothesis, those with another interpretation in reach: see ``contested_fraction``),
    ``association_precision``, ``association_recall``, ``loop_closures`` (events),
    ``loop_closure_precision`` (``data_association``).
divergence (``workbench.metrics.divergence``, from the estimate alone): ``diverged_at_s``
    (when its sightings left their gates for good, or its position left the mapped area;
    None when it held) and ``divergence`` (the evidence, one line).
frames (``frame_metrics``): ``frames``, ``frames_without_pose`` and the first of their times
    ``frames_without_pose_t``: where the data expect a pose (a landmark scan, a lidar frame)
    and the estimate has none.
cost: ``steps`` (timing entries = measurements processed; without timing, causal pose
    records), ``time_per_step_ms_median``, ``time_per_step_ms_p99``, ``time_total_s``,
    ``time_per_frame_ms`` (``time_total_s`` over ``frames``, None without frames).
front end (``workbench.metrics.frontend_agreement``, on a sequence with a lidar front end,
``Sequence.front_end``; every key None without one): the front end's own figures
    ``frontend_name``, ``frontend_frames``, ``frontend_ate_rmse_m`` (its trajectory scored
    as an estimate is, None without truth), ``frontend_ms_per_frame``,
    ``frontend_reobservation_nis_per_dof`` (its corners' re-observations); the scored
    history against its trajectory, aligned at the start: ``frontend_frames_compared``,
    ``frontend_path_length_m``, ``frontend_max_deviation_m``,
    ``frontend_max_deviation_percent_path``, ``frontend_final_yaw_diff_deg`` (estimate
    minus front end); the departure check (chi-square on yaw and horizontal position):
    ``frontend_departure_covariance`` (the rule used, or why not tested),
    ``frontend_departure_max_nees`` and ``_t_s``, ``frontend_departure_bound``,
    ``frontend_departure_false_alarm_rate`` (per run), and at the first frame over the bound
    ``frontend_departure_t_s``, ``frontend_departure_nees``, ``frontend_departure_yaw_deg``,
    ``frontend_departure_position_m`` (None when it stayed within).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError
from datasets.estimate import Estimate
from datasets.sequence import Sequence
from datasets.state import GroundTruth, LandmarkMap, StateHistory
from datasets.trajectory import Trajectory
from workbench.metrics.ate import ate_errors, paired_trajectories
from workbench.metrics.consistency import below_fraction, inside_fraction
from workbench.metrics.data_association import (
    landmark_id_mapping,
    majority_mapping,
    score_associations,
    score_loop_closures,
    true_ids_of_records,
)
from workbench.metrics.frontend_agreement import frontend_metrics
from workbench.metrics.orientation import orientation_error_rad, planar_orientation_error_rad
from workbench.metrics.rpe import kitti_segment_errors, rpe_errors
from workbench.metrics.state_errors import (
    landmark_errors,
    landmark_nees_series,
    nees_series,
    truth_pose_at,
)
from workbench.metrics.timestamps import straddles, trusted_samples, vectors_at

Metrics = dict[str, float | int | None]

ACCURACY_KEYS = (
    "ate_rmse_m",
    "ate_rmse_raw_m",
    "rpe_trans_rmse_m",
    "rpe_rot_rmse_deg",
    "final_orientation_error_deg",
    "kitti_translation_percent",
    "kitti_rotation_deg_per_100m",
    "gps_holdout_rmse_m",
)
CONSISTENCY_KEYS = (
    "nees_pose_per_dof",
    "nees_pose_inside_fraction",
    "nees_attitude_per_dof",
    "nees_position_per_dof",
    "nees_velocity_per_dof",
    "nees_gyro_bias_per_dof",
    "nees_accel_bias_per_dof",
    "nees_landmarks_per_dof",
)
UNIT_SUFFIXES = ("_m2", "_deg2", "_m", "_deg", "_ms", "_s")
"""Units a metric key ends with (the longer first: ``_m2`` before ``_m``)."""


def smoothed_key(key: str) -> str:
    """``ate_rmse_m`` -> ``ate_rmse_smoothed_m``; ``nees_pose_per_dof`` -> ``nees_pose_per_dof_smoothed``."""
    for unit in UNIT_SUFFIXES:
        if key.endswith(unit):
            return key[: -len(unit)] + "_smoothed" + unit
    return key + "_smoothed"


def _number(value: float | int | None) -> float | None:
    """A finite Python float, or None."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _per_dof(values: np.ndarray, dofs: np.ndarray) -> float | None:
    """Sum of the finite NEES (or NIS) values over the sum of their dof: 1 when consistent,
    whatever the blocks' sizes (NaN values, from singular covariances, left out)."""
    values = np.asarray(values, dtype=float)
    dofs = np.broadcast_to(np.asarray(dofs, dtype=float), values.shape)
    finite = np.isfinite(values)
    if not finite.any() or dofs[finite].sum() <= 0:
        return None
    return _number(values[finite].sum() / dofs[finite].sum())


def _finite_mean(values: np.ndarray) -> float | None:
    values = np.asarray(values, dtype=float)
    finite = values[np.isfinite(values)]
    return _number(np.mean(finite)) if finite.size else None


def _rmse(errors: np.ndarray) -> float | None:
    errors = np.asarray(errors, dtype=float)
    return _number(math.sqrt(float(np.mean(errors**2)))) if errors.size else None


MIN_SCORED_POSES = 3
"""Fewer poses paired with a finite reference give n/a accuracy, not a number."""


@dataclass(frozen=True)
class ScoredPairs:
    """The pose pairs a run is scored on, computed once (``scored_pairs``) and read by
    metrics.json, the evo result files and the tables alike.

    Attributes:
        reference, estimate: the paired truth and estimate (evo's nearest-stamp pairing,
            truth inside ``GroundTruth.excluded`` and non-finite truth rows left out), (N,).
        align: ``se3`` or ``se2`` (by dimension).
        ate: aligned position errors [m], (N,). ate_raw: without alignment [m], (N,).
        rpe_pairs: (M, 2) index pairs of the 1-frame RPE (pairs across an excluded interval
            left out); rpe_trans [m], rpe_rot_deg [deg]: their errors, (M,).
    """

    reference: Trajectory
    estimate: Trajectory
    align: str
    ate: np.ndarray
    ate_raw: np.ndarray
    rpe_pairs: np.ndarray
    rpe_trans: np.ndarray
    rpe_rot_deg: np.ndarray


def scored_pairs(pose: Trajectory | None, ground_truth: GroundTruth | None) -> ScoredPairs | None:
    """The pairs ``pose`` is scored on against ``ground_truth`` (``ScoredPairs``), or None
    when fewer than ``MIN_SCORED_POSES`` pair (an alignment needs three)."""
    if pose is None or len(pose) == 0 or ground_truth is None:
        return None
    if ground_truth.pose is None or len(ground_truth.pose) == 0:
        return None
    excluded = ground_truth.excluded
    try:
        reference, estimate = paired_trajectories(
            trusted_samples(ground_truth.pose, excluded), pose
        )
    except InputError:
        return None  # no stamps in common: nothing to compare
    finite = np.all(np.isfinite(reference.positions), axis=1)
    if excluded:
        finite &= ground_truth.trusted(estimate.t)  # no estimate scored inside an interval
    if int(finite.sum()) < MIN_SCORED_POSES:
        return None  # n/a, never a number from one or two poses
    reference, estimate = (
        reference.select(np.flatnonzero(finite)),
        estimate.select(np.flatnonzero(finite)),
    )
    align = "se3" if pose.dimension == 3 else "se2"
    ate = ate_errors(reference, estimate, align, allow_degenerate=True)[0]
    ate_raw = ate_errors(reference, estimate, "none")[0]
    pairs, trans, rot_deg = rpe_errors(reference, estimate, 1, "frames")
    if excluded and len(pairs):
        # a "1-frame" pair across an excluded interval would span untrusted truth
        whole = ~straddles(reference.t[pairs[:, 0]], reference.t[pairs[:, 1]], excluded)
        pairs, trans, rot_deg = pairs[whole], trans[whole], rot_deg[whole]
    return ScoredPairs(reference, estimate, align, ate, ate_raw, pairs, trans, rot_deg)


def accuracy_metrics(
    pose: Trajectory | None, ground_truth: GroundTruth | None, scored: ScoredPairs | None = None
) -> Metrics:
    """ATE, RPE, final orientation error and held-out GPS RMSE of one pose history
    (``scored``: its ``scored_pairs``, when the caller has them already)."""
    metrics: Metrics = dict.fromkeys(ACCURACY_KEYS)
    if pose is None or len(pose) == 0 or ground_truth is None:
        return metrics
    metrics["gps_holdout_rmse_m"] = _holdout_rmse(pose, ground_truth)
    scored = scored or scored_pairs(pose, ground_truth)
    if scored is None:
        return metrics
    metrics["ate_rmse_m"] = _rmse(scored.ate)
    metrics["ate_rmse_raw_m"] = _rmse(scored.ate_raw)
    if len(scored.estimate) >= 2:
        metrics["rpe_trans_rmse_m"] = _rmse(scored.rpe_trans)
        metrics["rpe_rot_rmse_deg"] = _rmse(scored.rpe_rot_deg)
        kitti = kitti_segment_errors(scored.reference, scored.estimate)
        metrics["kitti_translation_percent"] = _number(kitti["translation_percent"])
        metrics["kitti_rotation_deg_per_100m"] = _number(kitti["rotation_deg_per_100m"])
    metrics["final_orientation_error_deg"] = _final_orientation_error_deg(pose, ground_truth)
    return metrics


def _final_orientation_error_deg(pose: Trajectory, ground_truth: GroundTruth) -> float | None:
    found = truth_pose_at(ground_truth, pose.t)
    if found is None or not np.any(found[1]) or found[0].dimension != pose.dimension:
        return None
    truth, valid = found
    last = int(np.flatnonzero(valid)[-1])
    if pose.dimension == 3:
        angle = orientation_error_rad(pose.rotations[last], truth.rotations[-1])
    else:
        angle = planar_orientation_error_rad(pose.rotations[last], truth.rotations[-1])
    return _number(np.rad2deg(angle))


def _holdout_rmse(pose: Trajectory, ground_truth: GroundTruth) -> float | None:
    if ground_truth.held_out_positions is None:
        return None
    stamps, positions = ground_truth.held_out_positions
    stamps = np.asarray(stamps, dtype=float)
    # the estimate is interpolated at the fixes, across whatever steps it reported
    estimated, valid = vectors_at(pose.t, pose.positions, stamps, max_gap_s=math.inf)
    if ground_truth.excluded:
        trusted = ground_truth.trusted(stamps)
        estimated, valid = estimated[trusted[valid]], valid & trusted
    if not np.any(valid):
        return None
    shared = min(estimated.shape[1], np.asarray(positions).shape[1])
    difference = estimated[:, :shared] - np.asarray(positions, dtype=float)[valid, :shared]
    return _rmse(np.linalg.norm(difference, axis=1))


def consistency_metrics(
    history: StateHistory | None,
    ground_truth: GroundTruth | None,
    mapping: dict[int, int],
    final_map: LandmarkMap | None = None,
) -> Metrics:
    """Mean NEES of every block, and the fraction of pose NEES inside the 95% interval."""
    metrics: Metrics = dict.fromkeys(CONSISTENCY_KEYS)
    if history is None or ground_truth is None:
        return metrics
    series = nees_series(history, ground_truth, mapping)
    if "landmarks" not in series and final_map is not None and final_map.covariances is not None:
        final_series = landmark_nees_series((final_map,), mapping, ground_truth)
        if final_series is not None:
            series["landmarks"] = final_series
    for block, values in series.items():
        key = f"nees_{block}_per_dof"
        if key in metrics:
            metrics[key] = _per_dof(values.nees, values.dof)
    if "pose" in series:
        metrics["nees_pose_inside_fraction"] = _number(
            inside_fraction(series["pose"].nees, series["pose"].dof)
        )
    return metrics


def nis_metrics(estimate: Estimate) -> Metrics:
    """NIS statistics of the estimate's innovations: per update (stacked, comparable across
    estimators) and per associated measurement."""
    diagnostics = estimate.diagnostics
    metrics: Metrics = {"nis_per_dof": None, "nis_update_inside_fraction": None}
    stacked = np.asarray(diagnostics.scan_nis, dtype=float)
    stacked_dof = np.asarray(diagnostics.scan_nis_dof, dtype=int)
    finite = np.isfinite(stacked)
    if np.any(finite) and stacked_dof[finite].sum() > 0:
        metrics["nis_per_dof"] = _number(stacked[finite].sum() / stacked_dof[finite].sum())
        metrics["nis_update_inside_fraction"] = _number(inside_fraction(stacked, stacked_dof))
    values = np.asarray(diagnostics.nis, dtype=float)
    dofs = np.asarray(diagnostics.nis_dof, dtype=int)
    if values.size == 0:
        return {
            **metrics,
            "nis_measurement_per_dof": None,
            "nis_dof": None,
            "nis_inside_fraction": None,
            "nis_below_95_fraction": None,
        }
    unique = np.unique(dofs)
    return {
        **metrics,
        "nis_measurement_per_dof": _per_dof(values, dofs),
        "nis_dof": int(unique[0]) if len(unique) == 1 else None,
        "nis_inside_fraction": _number(inside_fraction(values, dofs)),
        "nis_below_95_fraction": _number(below_fraction(values, dofs)),
    }


def map_metrics(
    final_map: LandmarkMap | None, ground_truth: GroundTruth | None, mapping: dict[int, int]
) -> Metrics:
    """RMSE [m] of the final map's mapped landmarks against the truth and their count, and
    the size of the final map."""
    in_map = None if final_map is None else int(len(final_map))
    if final_map is None or ground_truth is None or ground_truth.landmarks is None:
        return {"landmark_rmse_m": None, "landmarks_mapped": None, "landmarks_in_map": in_map}
    errors, valid = landmark_errors(final_map, mapping, ground_truth)
    count = int(np.sum(valid))
    rmse = _rmse(np.linalg.norm(errors, axis=1)) if count else None
    return {"landmark_rmse_m": rmse, "landmarks_mapped": count, "landmarks_in_map": in_map}


def contested_fraction(diagnostics) -> float | None:
    """Of the sightings decided geometrically by one hypothesis, the fraction that had
    another interpretation within the new-landmark gate (``assoc_alternatives`` >= 1): the
    decisions a single-hypothesis association could have got wrong. None where nothing was
    judged so (ids, multiple hypotheses, runs recorded before the figure existed)."""
    alternatives = np.asarray(diagnostics.assoc_alternatives)
    judged = alternatives >= 0
    return _number(np.mean(alternatives[judged] >= 1)) if judged.any() else None


def association_metrics(estimate: Estimate, ground_truth: GroundTruth | None) -> Metrics:
    """Association precision/recall and loop-closure counts and precision."""
    diagnostics = estimate.diagnostics
    decisions = np.asarray(diagnostics.assoc_decision)
    sightings = len(decisions)

    def fraction(mask: np.ndarray) -> float | None:
        return _number(np.mean(mask)) if sightings else None

    metrics: Metrics = {
        "association_rejected_fraction": fraction(decisions == "rejected"),
        "association_ambiguous_fraction": fraction(decisions == "ambiguous"),
        "association_inflated_fraction": fraction(np.asarray(diagnostics.assoc_inflation) > 1.0),
        "association_contested_fraction": contested_fraction(diagnostics),
        "association_precision": None,
        "association_recall": None,
        "loop_closures": sum(1 for event in diagnostics.events if event.kind == "loop_closure"),
        "loop_closure_precision": None,
    }
    if ground_truth is None or not ground_truth.scan_ids or len(diagnostics.assoc_t) == 0:
        return metrics
    score = score_associations(diagnostics, ground_truth.scan_ids)
    metrics["association_precision"] = _number(score.precision)
    metrics["association_recall"] = _number(score.recall)
    mapping = majority_mapping(
        diagnostics.assoc_landmark_id, true_ids_of_records(diagnostics, ground_truth.scan_ids)
    )
    metrics["loop_closure_precision"] = _number(
        score_loop_closures(diagnostics.events, mapping).precision
    )
    return metrics


FRAME_TOLERANCE_S = 0.01
"""A pose within this of a frame's time [s] is that frame's (evo's pairing tolerance)."""


def frame_metrics(estimate: Estimate) -> Metrics:
    """``frames`` (times where the data expect a pose: ``Estimate.frame_times``),
    ``frames_without_pose`` (of them, those the scored history has no pose at: the causal
    one, else the smoothed one) and ``frames_without_pose_t`` (the first 20 of their times
    [s]); None when the run recorded no frames."""
    frames = estimate.frame_times
    if frames is None or len(frames) == 0:
        return {"frames": None, "frames_without_pose": None, "frames_without_pose_t": None}
    history = estimate.causal if estimate.causal.pose is not None else estimate.smoothed
    poses = np.zeros(0) if history is None or history.pose is None else history.pose.t
    if len(poses):
        after = np.clip(np.searchsorted(poses, frames), 0, len(poses) - 1)
        before = np.clip(after - 1, 0, len(poses) - 1)
        nearest = np.minimum(np.abs(poses[after] - frames), np.abs(poses[before] - frames))
        missing = nearest > FRAME_TOLERANCE_S
    else:
        missing = np.ones(len(frames), dtype=bool)
    return {
        "frames": int(len(frames)),
        "frames_without_pose": int(missing.sum()),
        "frames_without_pose_t": [float(t) for t in frames[missing][:20]],
    }


def cost_metrics(estimate: Estimate) -> Metrics:
    """Step count and per-step wall-clock time."""
    timing = estimate.timing
    if timing is None or len(timing.seconds) == 0:
        pose = estimate.causal.pose
        steps = (
            len(pose)
            if pose is not None
            else max((len(b.t) for b in estimate.causal.blocks.values()), default=0)
        )
        return {
            "steps": int(steps),
            "time_per_step_ms_median": None,
            "time_per_step_ms_p99": None,
            "time_total_s": None,
        }
    milliseconds = 1000.0 * np.asarray(timing.seconds, dtype=float)
    return {
        "steps": int(len(milliseconds)),
        "time_per_step_ms_median": _number(np.median(milliseconds)),
        "time_per_step_ms_p99": _number(np.percentile(milliseconds, 99)),
        "time_total_s": _number(float(np.sum(timing.seconds)) + float(timing.finalize_seconds)),
    }


def compute_metrics(
    estimate: Estimate, sequence: Sequence, scored: dict[str, ScoredPairs] | None = None
) -> Metrics:
    """The flat metrics dictionary of one run (see the module docstring for every key).
    ``scored``: filled with the ``ScoredPairs`` of the causal and smoothed histories
    (``causal``, ``smoothed``), for the caller that writes them elsewhere (the evo files)."""
    ground_truth = sequence.ground_truth
    mapping: dict[int, int] = {}
    if ground_truth is not None:
        mapping = landmark_id_mapping(estimate.diagnostics, ground_truth)

    metrics: Metrics = {}
    causal_pairs = scored_pairs(estimate.causal.pose, ground_truth)
    metrics.update(accuracy_metrics(estimate.causal.pose, ground_truth, causal_pairs))
    metrics.update(consistency_metrics(estimate.causal, ground_truth, mapping, estimate.landmarks))
    smoothed = estimate.smoothed
    smoothed_pose = smoothed.pose if smoothed is not None else None
    smoothed_pairs = scored_pairs(smoothed_pose, ground_truth)
    smoothed_accuracy = accuracy_metrics(smoothed_pose, ground_truth, smoothed_pairs)
    if scored is not None:
        scored.update(
            {
                name: pairs
                for name, pairs in (("causal", causal_pairs), ("smoothed", smoothed_pairs))
                if pairs is not None
            }
        )
    smoothed_consistency = consistency_metrics(smoothed, ground_truth, mapping)
    metrics.update(
        {
            smoothed_key(key): value
            for key, value in {**smoothed_accuracy, **smoothed_consistency}.items()
        }
    )
    metrics.update(relations_metrics(estimate.causal.pose, ground_truth))
    smoothed_relations = relations_metrics(
        smoothed.pose if smoothed is not None else None, ground_truth
    )
    smoothed_relations.pop("relations_max_diff_s")
    metrics.update({smoothed_key(key): value for key, value in smoothed_relations.items()})
    metrics.update(nis_metrics(estimate))
    metrics.update(map_metrics(estimate.landmarks, ground_truth, mapping))
    metrics.update(association_metrics(estimate, ground_truth))
    metrics.update(divergence_metrics(estimate, sequence))
    metrics.update(frame_metrics(estimate))
    metrics.update(cost_metrics(estimate))
    total, frames = metrics["time_total_s"], metrics["frames"]
    metrics["time_per_frame_ms"] = 1e3 * total / frames if total is not None and frames else None
    metrics.update(frontend_metrics(estimate, sequence))
    return metrics


def relations_metrics(pose: Trajectory | None, ground_truth: GroundTruth | None) -> Metrics:
    """The relations metric of one pose history against ``ground_truth.relations``
    (``workbench.metrics.relations.relation_errors``: Kümmerle et al., "On measuring the
    accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009).

    Keys: ``relations_trans_error_{mean,std}_m`` [m], ``relations_rot_error_{mean,std}_deg``
    [deg], ``relations_trans_error_sq_mean_m2`` [m^2], ``relations_rot_error_sq_mean_deg2``
    [deg^2], ``relations_used``, ``relations_skipped``, ``relations_skipped_reasons`` (one
    line, None when none was skipped) and ``relations_max_diff_s`` (the stamp tolerance
    [s]). All None when there are no relations or no pose history; the statistics None where
    undefined (nothing scored, a std of fewer than two relations).
    """
    from workbench.metrics.relations import relation_errors

    statistics = (
        "trans_error_mean_m",
        "trans_error_std_m",
        "rot_error_mean_deg",
        "rot_error_std_deg",
        "trans_error_sq_mean_m2",
        "rot_error_sq_mean_deg2",
    )
    counts = ("used", "skipped", "skipped_reasons", "max_diff_s")
    metrics: Metrics = dict.fromkeys(f"relations_{name}" for name in statistics + counts)
    relations = None if ground_truth is None else ground_truth.relations
    if relations is None or pose is None:
        return metrics
    result = relation_errors(pose, relations)
    found = result.statistics()
    metrics.update({f"relations_{name}": _number(found[name]) for name in statistics})
    metrics["relations_used"] = result.used_count
    metrics["relations_skipped"] = result.skipped_count
    metrics["relations_skipped_reasons"] = result.skipped_text()
    metrics["relations_max_diff_s"] = result.max_diff_s
    return metrics


def divergence_metrics(estimate: Estimate, sequence: Sequence) -> Metrics:
    """``diverged_at_s`` and ``divergence`` (the evidence), None when the run held
    (``workbench.metrics.divergence``: no truth of the trajectory needed)."""
    from workbench.metrics.divergence import detect_divergence

    found = detect_divergence(estimate, sequence)
    return {
        "diverged_at_s": None if found is None else found.t,
        "divergence": None if found is None else found.reason,
    }
