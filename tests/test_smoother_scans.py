"""Landmark scans in the smoothers: one typed decision per sighting with its reason, the
scan NIS against the keyframe's prediction (with ids too), the prediction's Jacobians,
anchors at the first keyframe, an id repeated within one keyframe."""

from __future__ import annotations

from dataclasses import replace

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import L, X

from datasets.estimate import AssociationDecision
from datasets.measurements import LandmarkScan
from filters.association import Reason
from smoothers.joint_marginals import JointMarginals
from smoothers.keyframe_prediction import KeyframePredictor
from smoothers.landmark_book import MapLandmark
from smoothers.landmark_scans import AT_SENSOR_ORIGIN
from smoothers.modes import SmootherFixedLag, SmootherIsam2
from workbench.registry import load_dataset


def _run(estimator_class, config, sequence):
    estimator = estimator_class(config, sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    return estimator, estimator.estimate()


def _with_stream(sequence, transform):
    items = transform(list(sequence.measurements()))
    return replace(sequence, stream=lambda: iter(items))


@pytest.fixture(scope="module")
def rover():
    return load_dataset("sim:aghili-rover", 1, {"duration_s": "3"})


def _check_records(estimate, sequence) -> None:
    """One record per sighting; used ones name their landmark, unused ones say why."""
    diagnostics = estimate.diagnostics
    sightings = sum(m.count for m in sequence.measurements() if isinstance(m, LandmarkScan))
    assert len(diagnostics.assoc_decision) == sightings
    used = np.isin(diagnostics.assoc_decision, ["matched", "new"])
    assert set(diagnostics.assoc_decision) <= {d.value for d in AssociationDecision}
    assert np.all(diagnostics.assoc_landmark_id[used] >= 0)
    assert np.all(diagnostics.assoc_landmark_id[~used] == -1)
    assert np.all(diagnostics.assoc_reason[~used] != "")
    assert np.all(diagnostics.assoc_reason[used] == "")


def test_every_sighting_has_a_typed_decision_and_the_unused_say_why(rover):
    """A repeated id and a sighting at the sensor origin are rejected with their reasons."""
    chosen = next(m.t for m in rover.measurements() if isinstance(m, LandmarkScan) and m.t > 1)

    def corrupt(items):
        out = []
        for m in items:
            if isinstance(m, LandmarkScan) and m.t == chosen:
                m = LandmarkScan(
                    m.t,
                    np.vstack([m.points, m.points[:1], np.zeros((1, 3))]),
                    np.concatenate([m.covariances, m.covariances[:2]]),
                    np.concatenate([m.ids, m.ids[:1], [9999]]),
                )
            out.append(m)
        return out

    sequence = _with_stream(rover, corrupt)
    for estimator_class in (SmootherIsam2, SmootherFixedLag):
        _, estimate = _run(estimator_class, estimator_class.Config(anchors=3), sequence)
        _check_records(estimate, sequence)
        diagnostics = estimate.diagnostics
        at = diagnostics.assoc_t == chosen
        reasons = diagnostics.assoc_reason[at & (diagnostics.assoc_decision == "rejected")]
        assert sorted(reasons) == sorted([Reason.REPEATED_ID.value, AT_SENSOR_ORIGIN])


def test_geometric_association_records_every_decision():
    sequence = load_dataset("sim:aghili-rover", 4, {"duration_s": "3", "ids": "false"})
    _, estimate = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)
    _check_records(estimate, sequence)
    assert np.any(estimate.diagnostics.assoc_decision == "matched")


def test_scan_nis_with_ids_stacks_the_matched_sightings_against_the_prediction(rover):
    estimator, estimate = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), rover)
    diagnostics = estimate.diagnostics
    scans = [m for m in rover.measurements() if isinstance(m, LandmarkScan)]
    # one stacked NIS per scan, dof = 3 x its matched sightings; new landmarks are not in it
    assert len(diagnostics.scan_nis) == len(scans)
    for t, dof in zip(diagnostics.scan_nis_t, diagnostics.scan_nis_dof, strict=True):
        matched = np.sum((diagnostics.assoc_t == t) & (diagnostics.assoc_decision == "matched"))
        assert dof == 3 * matched
        assert np.all(diagnostics.nis_dof[diagnostics.nis_t == t] == 3)
        assert diagnostics.nis_dof[diagnostics.nis_t == t].sum() == dof
    new_at_start = np.sum(
        (diagnostics.assoc_t == scans[0].t) & (diagnostics.assoc_decision == "new")
    )
    assert new_at_start > 0 and diagnostics.scan_nis_dof[0] == 3 * estimator.config.anchors
    # the model matches the simulation: the NIS per dof is about 1 (41 scans, ~1300 dof)
    assert 0.8 < diagnostics.scan_nis.sum() / diagnostics.scan_nis_dof.sum() < 1.25
    # without the prediction's query nothing is scored
    _, quiet = _run(
        SmootherIsam2,
        SmootherIsam2.Config(anchors=3, innovation_nis=False, id_gate_probability=None),
        rover,
    )
    assert len(quiet.diagnostics.scan_nis) == 0 and len(quiet.diagnostics.nis) == 0


def _predictor_case(dimension: int):
    """A pose and two landmarks in iSAM2 with correlated marginals."""
    rng = np.random.default_rng(dimension)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    if dimension == 3:
        pose = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.3, -0.2, 0.9), np.array([1.0, -2.0, 0.5]))
        graph.add(gtsam.PriorFactorPose3(X(0), pose, gtsam.noiseModel.Isotropic.Sigma(6, 0.1)))
        values.insert(X(0), pose)
    else:
        pose = gtsam.Pose2(1.0, -2.0, 0.7)
        graph.add(gtsam.PriorFactorPose2(X(0), pose, gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
        values.insert(X(0), pose)
    positions = rng.normal(size=(2, dimension)) * 5.0
    for i, position in enumerate(positions):
        prior = gtsam.PriorFactorPoint3 if dimension == 3 else gtsam.PriorFactorPoint2
        graph.add(prior(L(i), position, gtsam.noiseModel.Isotropic.Sigma(dimension, 0.5)))
        # a relative measurement correlates the landmark with the pose
        delta = gtsam.BetweenFactorPoint3 if dimension == 3 else gtsam.BetweenFactorPoint2
        if i == 1:
            graph.add(
                delta(
                    L(0),
                    L(1),
                    positions[1] - positions[0],
                    gtsam.noiseModel.Isotropic.Sigma(dimension, 0.2),
                )
            )
        values.insert(L(i), position)
    isam = gtsam.ISAM2()
    isam.update(graph, values)
    return pose, positions, isam


@pytest.mark.parametrize("dimension", [2, 3])
def test_prediction_covariance_is_h_j_h_transpose_with_numerical_jacobians(dimension):
    pose, positions, isam = _predictor_case(dimension)
    candidates = [MapLandmark(map_id=i, key=L(i)) for i in range(2)]
    predictor = KeyframePredictor(
        pose,
        X(0),
        candidates,
        positions,
        lambda keys, t=0.0: JointMarginals.query(isam, keys),
        dimension,
    )
    predicted, covariance = predictor.joint(np.array([1, 0]))

    def measure(pose_delta: np.ndarray, landmark_delta: np.ndarray) -> np.ndarray:
        moved = pose.retract(pose_delta)  # GTSAM's tangent, right perturbation
        points = positions[[1, 0]] + landmark_delta.reshape(2, dimension)
        return np.array([moved.transformTo(point) for point in points]).ravel()

    pose_dof = 6 if dimension == 3 else 3
    step = 1e-6
    jacobian = np.zeros((2 * dimension, pose_dof + 2 * dimension))
    for column in range(pose_dof + 2 * dimension):
        delta = np.zeros(pose_dof + 2 * dimension)
        delta[column] = step
        plus = measure(delta[:pose_dof], delta[pose_dof:])
        minus = measure(-delta[:pose_dof], -delta[pose_dof:])
        jacobian[:, column] = (plus - minus) / (2 * step)
    joint = JointMarginals.query(isam, [X(0), L(0), L(1)]).matrix([X(0), L(1), L(0)])
    np.testing.assert_allclose(
        predicted.ravel(), measure(np.zeros(pose_dof), np.zeros(2 * dimension))
    )
    np.testing.assert_allclose(covariance, jacobian @ joint @ jacobian.T, rtol=1e-6, atol=1e-9)


def test_anchors_seen_at_the_first_keyframe_are_matched_not_mapped_again():
    sequence = load_dataset("sim:aghili-rover", 4, {"duration_s": "2", "ids": "false"})
    _, estimate = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)
    diagnostics = estimate.diagnostics
    first_t, true_ids = sequence.ground_truth.scan_ids[0]
    anchors = {int(i) for i in sequence.known_landmarks.ids[:3]}
    at_first = diagnostics.assoc_t == first_t
    for index, true_id in enumerate(true_ids):
        if int(true_id) in anchors:
            row = at_first & (diagnostics.assoc_measurement_index == index)
            assert diagnostics.assoc_decision[row][0] == "matched"
            assert diagnostics.assoc_landmark_id[row][0] == int(true_id)


def test_an_id_new_in_two_scans_of_one_keyframe_is_one_landmark(rover):
    first = next(m.t for m in rover.measurements() if isinstance(m, LandmarkScan))

    def twice(items):
        out = []
        for m in items:
            out.append(m)
            if isinstance(m, LandmarkScan) and m.t == first:
                out.append(m)
        return out

    sequence = _with_stream(rover, twice)
    estimator, estimate = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)
    variables = [
        key for key in estimator.backend.estimate().keys() if chr(gtsam.Symbol(key).chr()) == "l"
    ]
    # the exported map leaves the 3 anchors (inputs, not estimates) out
    anchored = sum(lm.anchor_position is not None for lm in estimator.landmarks.values())
    assert anchored == 3
    assert len(variables) == len(estimator.landmarks) == len(estimate.landmarks) + anchored
    decisions = estimate.diagnostics.assoc_decision[estimate.diagnostics.assoc_t == first]
    second = decisions[len(decisions) // 2 :]  # the repeated scan's records
    assert len(second) and np.all(second == "matched")
