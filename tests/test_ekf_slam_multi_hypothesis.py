"""ekf-slam-mht: the ranked scan hypotheses (Murty's enumeration against brute force, the
joint likelihood against scipy), the composed odometry its hypotheses predict with
(against predicting every sample), and association without ids on UTIAS and the
simulator."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from datasets.errors import InputError
from datasets.measurements import LandmarkScan, Odometry
from datasets.utias import load
from filters.association.hypotheses import _murty, ranked_hypotheses
from filters.ekf_slam.config import EkfSlamConfig, MultiHypothesisEkfSlamConfig
from filters.ekf_slam.filter import EkfSlam
from filters.ekf_slam.motion import compose_planar
from filters.ekf_slam.motion_input import planar_odometry_step
from filters.ekf_slam.multi_hypothesis import MultiHypothesisEkfSlam
from workbench.metrics.summary import compute_metrics
from workbench.registry import load_dataset
from workbench.runner import run_estimator


def _brute_force(cost: np.ndarray) -> list[float]:
    rows, columns = cost.shape
    totals = []
    for chosen in itertools.permutations(range(columns), rows):
        total = sum(cost[row, column] for row, column in enumerate(chosen))
        if np.isfinite(total):
            totals.append(total)
    return sorted(totals)


def test_murty_enumerates_the_k_best_assignments_in_order() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        cost = rng.uniform(-2.0, 5.0, size=(4, 7))
        cost[rng.uniform(size=cost.shape) < 0.35] = np.inf
        cost[np.arange(4), 3 + np.arange(4)] = rng.uniform(0.0, 5.0, size=4)  # always feasible
        expected = _brute_force(cost)[:12]
        found = _murty(cost, 12)
        totals = [float(cost[np.arange(4), columns].sum()) for columns in found]
        assert len({tuple(columns) for columns in found}) == len(found)  # distinct
        np.testing.assert_allclose(totals, expected, rtol=0, atol=1e-9)


class _FixedPredictor:
    """Predictions of m landmarks with a fixed joint covariance (m*d, m*d)."""

    def __init__(self, predicted: np.ndarray, joint: np.ndarray) -> None:
        self.predicted, self.joint_cov = predicted, joint
        self.d = predicted.shape[1]

    def _rows(self, indices: np.ndarray) -> np.ndarray:
        return (np.asarray(indices)[:, None] * self.d + np.arange(self.d)).ravel()

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        blocks = np.stack(
            [self.joint_cov[np.ix_(self._rows([i]), self._rows([i]))] for i in indices]
        )
        return self.predicted[indices], blocks

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rows = self._rows(np.asarray(indices))
        return self.predicted[np.asarray(indices)], self.joint_cov[np.ix_(rows, rows)]


def test_hypotheses_are_scored_by_the_joint_likelihood_of_the_scan() -> None:
    rng = np.random.default_rng(7)
    m, d = 4, 2
    predicted = np.array([[1.0, 0.0], [1.4, 0.1], [3.0, 1.0], [0.0, 2.0]])
    factor = rng.normal(size=(m * d, m * d)) * 0.05
    joint = factor @ factor.T + 0.01 * np.eye(m * d)  # correlated, like a shared pose error
    measured = np.array([[1.1, 0.05], [1.35, 0.12], [5.0, 5.0]])
    measured_cov = np.stack([np.diag([0.01, 0.02])] * 3)
    log_density = np.log(1e-3)
    hypotheses = ranked_hypotheses(
        measured,
        measured_cov,
        m,
        _FixedPredictor(predicted, joint),
        gate_probability=0.9999,
        new_landmark_log_density=log_density,
        count=5,
    )
    assert len(hypotheses) == 5
    scores = [h.log_likelihood for h in hypotheses]
    assert scores == sorted(scores, reverse=True)
    for hypothesis in hypotheses:
        paired = np.flatnonzero(hypothesis.candidates >= 0)
        landmarks = hypothesis.candidates[paired]
        assert len(set(landmarks)) == len(landmarks)
        rows = (landmarks[:, None] * d + np.arange(d)).ravel()
        covariance = joint[np.ix_(rows, rows)].copy()
        for local, j in enumerate(paired):
            covariance[local * d : local * d + d, local * d : local * d + d] += measured_cov[j]
        expected = (len(measured) - len(paired)) * log_density
        if len(paired):
            innovation = (measured[paired] - predicted[landmarks]).ravel()
            expected += multivariate_normal(np.zeros(len(rows)), covariance).logpdf(innovation)
        assert hypothesis.log_likelihood == pytest.approx(expected, abs=1e-9)
    # the far sighting (5, 5) is in no gate: new in every hypothesis; the best pairs the others
    assert all(h.candidates[2] == -1 for h in hypotheses)
    assert list(hypotheses[0].candidates[:2]) == [0, 1]
    association = hypotheses[0].association(measured_cov)
    assert association.mode == "multi-hypothesis"
    assert [d.value for d in association.decisions] == ["matched", "matched", "new"]


def test_composed_odometry_predicts_like_every_sample() -> None:
    # every sample here is a "gap" (max_gap_s below the 0.01 s step): the gap widening is
    # composed too; FEJ's transition column starts at the prediction before the update
    sequence = load_dataset(
        "sim:guerreiro-loop", 0, {"duration_s": "4", "odometry": "true", "ids": "false"}
    )
    config = EkfSlamConfig(max_gap_s=0.001)
    sequential = EkfSlam(config, sequence)
    measurements = iter(sequence.measurements())
    scans = 0
    for measurement in measurements:
        sequential.process(measurement)
        if isinstance(measurement, LandmarkScan) and len(measurement.points):
            scans += 1
            if scans == 3:
                break
    assert np.linalg.norm(sequential.predicted_position - sequential.vehicle.position) > 0
    composed = sequential.branch()
    pending, count, motion_t = None, 0, composed.motion_t
    for measurement in measurements:  # the scans between are left out of both
        if not isinstance(measurement, Odometry):
            continue
        if count == 20:
            break
        sequential.process(measurement)
        step = planar_odometry_step(
            config, sequence.noise.odometry, measurement, measurement.t - motion_t
        )
        pending = step if pending is None else compose_planar(*pending, *step)
        motion_t, count = measurement.t, count + 1
    composed.advance_planar(*pending, motion_t)
    np.testing.assert_allclose(composed.vehicle.position, sequential.vehicle.position, atol=1e-12)
    assert float(composed.vehicle.rotation) == pytest.approx(
        float(sequential.vehicle.rotation), abs=1e-12
    )
    scale = np.abs(sequential.covariance).max()
    np.testing.assert_allclose(
        composed.covariance, sequential.covariance, rtol=0, atol=1e-10 * scale
    )
    assert composed.motion_t == sequential.motion_t


@pytest.mark.study
def test_utias_robot1_without_ids_keeps_the_right_association(utias_folder: Path) -> None:
    # 180 s of robot 1, ids withheld (scored with them): ekf-slam's single-scan decisions
    # pair sightings of unmapped landmarks with mapped neighbours (P 0.922 when written);
    # the hypotheses keep them apart until the data decide (P 0.997, R 0.997; 16 s here)
    sequence = load(f"{utias_folder}#robot1", 0, {"duration_s": "180", "ids": "false"})
    single = compute_metrics(run_estimator(EkfSlam, EkfSlamConfig(), sequence), sequence)
    estimate = run_estimator(MultiHypothesisEkfSlam, MultiHypothesisEkfSlamConfig(), sequence)
    multiple = compute_metrics(estimate, sequence)
    assert single["association_precision"] < 0.95
    assert multiple["association_precision"] >= 0.99
    assert multiple["association_recall"] >= 0.99
    assert multiple["ate_rmse_m"] < single["ate_rmse_m"]
    assert any("hypotheses kept" in note for note in estimate.notes)
    assert any("sequence's P_D by range" in note for note in estimate.notes)
    assert len(estimate.diagnostics.extras["hypotheses"]) > 0


def test_simulated_loop_without_ids_is_consistent() -> None:
    # model-matched odometry and laser: every sighting paired right, scan NIS per dof
    # inside its 99 % chi-square band (few hypotheses: the scenario has little ambiguity)
    sequence = load_dataset(
        "sim:guerreiro-loop", 1, {"duration_s": "12", "odometry": "true", "ids": "false"}
    )
    config = MultiHypothesisEkfSlamConfig(max_hypotheses=8)
    estimate = run_estimator(MultiHypothesisEkfSlam, config, sequence)
    metrics = compute_metrics(estimate, sequence)
    assert metrics["association_precision"] == 1.0
    assert metrics["association_recall"] >= 0.99
    diagnostics = estimate.diagnostics
    dof = int(diagnostics.scan_nis_dof.sum())
    from scipy.stats import chi2

    low, high = chi2.ppf([0.005, 0.995], dof) / dof
    assert low <= diagnostics.scan_nis.sum() / dof <= high
    pose = estimate.causal.pose
    assert pose is not None and np.all(np.linalg.eigvalsh(pose.covariances) > 0)


def test_missed_detections_are_priced_for_landmarks_in_view() -> None:
    # landmarks 0 and 1 in view, 2 and 3 out, each with its own P_D (a model by range):
    # each pairing adds log P_D, each landmark in view left unpaired log(1 - P_D), on top
    # of the scores without the term
    predicted = np.array([[1.0, 0.0], [1.4, 0.1], [3.0, 1.0], [0.0, 2.0]])
    joint = 0.01 * np.eye(8)
    measured = np.array([[1.02, 0.01]])
    measured_cov = np.stack([np.diag([0.01, 0.01])])
    visible = np.array([True, True, False, False])
    probability = np.array([0.3, 0.6, 0.2, 0.5])
    common = dict(gate_probability=0.9999, new_landmark_log_density=np.log(1e-3), count=4)
    plain = ranked_hypotheses(
        measured, measured_cov, 4, _FixedPredictor(predicted, joint), **common
    )
    priced = ranked_hypotheses(
        measured,
        measured_cov,
        4,
        _FixedPredictor(predicted, joint),
        detection=lambda points: (probability[: len(points)], visible[: len(points)]),
        **common,
    )
    before = {tuple(h.candidates): h.log_likelihood for h in plain}
    assert len(priced) == len(plain) == 3  # pair with 0, with 1, or new
    for hypothesis in priced:
        paired = hypothesis.candidates[hypothesis.candidates >= 0]
        unseen = visible.copy()
        unseen[paired] = False
        expected = before[tuple(hypothesis.candidates)] + np.log(probability[paired]).sum()
        expected += np.log1p(-probability[unseen]).sum()
        assert hypothesis.log_likelihood == pytest.approx(expected, abs=1e-9)


@pytest.mark.study
def test_n_scan_back_pruning_keeps_only_the_best_hypothesis_s_old_decisions() -> None:
    """``commit_after_s``: every hypothesis kept descends from the best one's ancestor of
    that long ago (its decisions then are settled); without it the kept hypotheses differ
    in decisions older than that (simulated loop without ids, 6 s, 8 hypotheses)."""
    sequence = load_dataset(
        "sim:guerreiro-loop", 1, {"duration_s": "6", "odometry": "true", "ids": "false"}
    )

    def ancestors(horizon: float | None, cut_s: float) -> set[int]:
        config = MultiHypothesisEkfSlamConfig(max_hypotheses=8, commit_after_s=horizon)
        estimator = MultiHypothesisEkfSlam(config, sequence)
        for measurement in sequence.measurements():
            estimator.process(measurement)
        assert len(estimator.hypotheses) > 1
        found = set()
        for hypothesis in estimator.hypotheses:
            history = hypothesis.history
            while history is not None and history[2] > estimator.t - cut_s:
                history = history[0]
            found.add(id(history))
        return found

    assert len(ancestors(None, 1.0)) > 1
    assert len(ancestors(1.0, 1.0)) == 1


def test_detection_probability_settings_parse_as_the_command_line_gives_them() -> None:
    # --set values are read as YAML: each documented setting must survive that
    from datasets.options import parse_options

    def parsed(text: str):
        config = parse_options(MultiHypothesisEkfSlamConfig, {"detection_probability": text}, "")
        return config.detection_probability

    assert parsed("sequence") == "sequence"
    assert parsed("none") == "none"
    assert parsed("0.4") == pytest.approx(0.4)
    with pytest.raises(InputError):
        parsed("1.5")
