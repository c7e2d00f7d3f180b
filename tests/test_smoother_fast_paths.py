"""The smoothers' fast paths: Cholesky with the automatic QR fallback (its event and note),
and batched joint marginal queries equal to the per-key ones."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import X

from datasets.errors import InputError
from smoothers import backends
from smoothers.backends import FixedLagBackend, Isam2Backend
from smoothers.covariances import pose_covariance
from smoothers.gtsam_errors import explain, gtsam_message
from smoothers.joint_marginals import JointMarginals
from smoothers.modes import SmootherBatch, SmootherFixedLag, SmootherIsam2
from workbench.registry import load_dataset


def _run(estimator_class, config, sequence):
    estimator = estimator_class(config, sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    return estimator, estimator.estimate()


def _stiff_step(backend) -> None:
    """A prior of 1 and a between factor of 1e-9 (rad, m): the information spans 18 orders
    of magnitude, so Cholesky's Schur complement cancels to a zero pivot; QR solves it."""
    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(), gtsam.noiseModel.Isotropic.Sigma(3, 1)))
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose2())
    backend.update(graph, values, {X(0): 0.0}, 0.0)
    graph = gtsam.NonlinearFactorGraph()
    graph.add(
        gtsam.BetweenFactorPose2(
            X(0), X(1), gtsam.Pose2(1, 0, 0), gtsam.noiseModel.Isotropic.Sigma(3, 1e-9)
        )
    )
    values = gtsam.Values()
    values.insert(X(1), gtsam.Pose2(1.0, 0.01, 0.0))
    backend.update(graph, values, {X(1): 1.0}, 1.0)


@pytest.mark.parametrize(
    "make",
    [
        lambda f: Isam2Backend(0.05, 1, 0, dimension=2, factorization=f),
        lambda f: FixedLagBackend(10.0, 0.05, 1, dimension=2, factorization=f),
    ],
    ids=["isam2", "fixed-lag"],
)
def test_cholesky_failure_redoes_the_step_with_qr_and_stays_on_qr(make):
    fallen, reference = make("CHOLESKY"), make("QR")
    _stiff_step(fallen)
    _stiff_step(reference)
    assert fallen.factorization == "QR" and reference.fallback is None
    assert fallen.fallback is not None and fallen.fallback.t == 1.0
    assert "ndeterminate" in fallen.fallback.reason and "x1" in fallen.fallback.reason
    for key in (X(0), X(1)):
        assert fallen.estimate().atPose2(key).equals(reference.estimate().atPose2(key), 1e-12)
    np.testing.assert_allclose(
        fallen.joint([X(0), X(1)]).matrix(), reference.joint([X(0), X(1)]).matrix(), atol=1e-12
    )


def test_qr_fallback_on_kitti_is_an_event_and_a_note_and_matches_qr_throughout():
    """kitti-imu-gps's tiny bias walk breaks Cholesky (keyframe every 10 IMU samples)."""
    sequence = load_dataset("kitti-imu-gps", 1, {"duration_s": "3"})
    for estimator_class in (SmootherIsam2, SmootherFixedLag):
        runs = {}
        for factorization in ("CHOLESKY", "QR"):
            config = estimator_class.Config(keyframe_imu_stride=10, factorization=factorization)
            runs[factorization] = _run(estimator_class, config, sequence)
        estimator, estimate = runs["CHOLESKY"]
        events = [e for e in estimate.diagnostics.events if e.kind == "factorization_fallback"]
        assert len(events) == 1 and events[0].details["to"] == "QR"
        assert "ndeterminate" in events[0].details["reason"]
        assert any("QR from there on" in note for note in estimate.notes)
        assert estimator.backend.factorization == "QR"
        _, reference = runs["QR"]
        assert not any(e.kind == "factorization_fallback" for e in reference.diagnostics.events)
        for label in ("causal", "smoothed"):
            ours, theirs = getattr(estimate, label).pose, getattr(reference, label).pose
            np.testing.assert_allclose(ours.positions, theirs.positions, atol=1e-9)
            # the causal marginals before the failure came from Cholesky: round-off of a
            # system whose information spans many orders of magnitude (measured 4e-7)
            scale = np.abs(theirs.covariances).max()
            np.testing.assert_allclose(ours.covariances, theirs.covariances, atol=1e-5 * scale)


def test_an_indeterminate_system_under_qr_too_is_an_input_error_with_the_whole_message():
    backend = Isam2Backend(0.05, 1, 0, dimension=2)
    graph = gtsam.NonlinearFactorGraph()
    graph.add(
        gtsam.BetweenFactorPose2(
            X(0), X(1), gtsam.Pose2(1, 0, 0), gtsam.noiseModel.Isotropic.Sigma(3, 0.1)
        )
    )
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose2())
    values.insert(X(1), gtsam.Pose2(1, 0, 0))
    with pytest.raises(InputError, match=r"QR after Cholesky failed.*indeterminate.*x\d") as info:
        backend.update(graph, values, {}, 3.5)
    assert "\n" not in str(info.value)


def test_gtsam_messages_are_kept_whole_on_one_line():
    error = RuntimeError("\nIndeterminant linear system detected\n  near variable x7\n\n")
    assert gtsam_message(error) == "Indeterminant linear system detected near variable x7"
    assert "near variable x7" in str(explain(error, 2.0, "iSAM2 update"))
    other = RuntimeError("\nkey l3 does not exist\n")
    assert str(explain(other, float("nan"), "joint")).endswith(
        "failed inside GTSAM: key l3 does not exist"
    )
    assert gtsam_message(RuntimeError("")) == "RuntimeError"


@pytest.fixture(scope="module")
def rover_isam2():
    sequence = load_dataset("sim:aghili-rover", 2, {"duration_s": "3"})
    return _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)


ROUND_OFF = 1e-11
"""Batched against per-key marginals: GTSAM eliminates a joint along another path than a
single key's marginal, so they agree to round-off, not bit for bit (measured on this run:
1.3e-12 absolute at most, on covariances up to 5e-4; relative to a block, 1.2e-9 at most,
on the bias blocks)."""


def _difference(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(np.asarray(a) - np.asarray(b)).max())


def test_batched_joint_marginals_equal_the_per_key_queries(rover_isam2):
    estimator, _ = rover_isam2
    isam = estimator.backend.isam
    keys = [key for key in isam.getLinearizationPoint().keys()]
    joint = estimator.backend.joint(keys)
    for key in keys:
        assert _difference(joint.marginalCovariance(key), isam.marginalCovariance(key)) < ROUND_OFF
    # an off-diagonal block against GTSAM's own pairwise joint, in either order
    a, b = keys[-1], keys[0]
    pair = isam.jointMarginalCovariance([a, b])
    block = joint.matrix([a, b])
    size = np.asarray(pair.at(a, a)).shape[0]
    assert _difference(block[:size, size:], pair.at(a, b)) < ROUND_OFF
    assert _difference(block[size:, :size], pair.at(b, a)) < ROUND_OFF
    # gtsam.Marginals (the batch mode's source) through the same class
    marginals = gtsam.Marginals(estimator.full_graph, isam.calculateEstimate())
    batched = JointMarginals.query(marginals, keys[:20])
    for key in keys[:20]:
        assert (
            _difference(batched.marginalCovariance(key), marginals.marginalCovariance(key))
            < ROUND_OFF
        )


def test_the_finish_reports_the_per_key_marginals(rover_isam2):
    estimator, estimate = rover_isam2
    isam = estimator.backend.isam
    covariances = estimate.smoothed.pose.covariances
    for k in (0, len(estimator.keyframe_t) // 2, len(estimator.keyframe_t) - 1):
        expected = pose_covariance(isam.marginalCovariance(estimator.motion.pose_key(k)))
        assert _difference(covariances[k], expected) < ROUND_OFF
    final = estimate.landmarks
    for row, map_id in enumerate(final.ids):
        key = estimator.landmarks[int(map_id)].key
        assert _difference(final.covariances[row], isam.marginalCovariance(key)) < ROUND_OFF


def test_fixed_lag_exports_and_batch_marginals_are_batched_and_well_formed():
    sequence = load_dataset("sim:aghili-rover", 3, {"duration_s": "3"})
    estimator, estimate = _run(
        SmootherFixedLag, SmootherFixedLag.Config(anchors=3, lag_s=0.5), sequence
    )
    assert len(estimator.exports.keyframes) > 10  # most keyframes left the window
    assert len(estimate.smoothed.pose) == len(estimator.keyframe_t)
    assert np.all(np.diff(estimate.smoothed.pose.t) > 0)
    _, batch = _run(SmootherBatch, SmootherBatch.Config(anchors=3), sequence)
    assert batch.causal.pose is None and batch.smoothed.pose.covariances is not None
    assert batch.landmarks.covariances is not None


def test_dense_qr_marginals_equal_gtsam_marginals_where_cholesky_works():
    from smoothers.dense_marginals import DenseQrMarginals

    rng = np.random.default_rng(0)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    graph.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(), gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
    values.insert(X(0), gtsam.Pose2())
    for k in range(1, 6):
        step = gtsam.Pose2(1.0, 0.1 * rng.standard_normal(), 0.2 * rng.standard_normal())
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.05, 0.02, 0.01]) * (1 + k))
        graph.add(gtsam.BetweenFactorPose2(X(k - 1), X(k), step, noise))
        values.insert(X(k), values.atPose2(X(k - 1)).compose(step))
    keys = [X(1), X(3), X(5)]
    dense = JointMarginals.query(DenseQrMarginals(graph, values), keys)
    reference = JointMarginals.query(gtsam.Marginals(graph, values), keys)
    np.testing.assert_allclose(dense.matrix(), reference.matrix(), rtol=1e-9, atol=1e-14)


def test_batch_marginals_fall_back_to_dense_qr_where_cholesky_fails():
    """A lateral velocity walk of zero (variance floored at 1e-12) makes the planar batch
    smoother's information matrix too ill-conditioned for Cholesky: the run finishes on the
    dense QR fallback, with its event and note, instead of raising."""
    sequence = load_dataset("sim:guerreiro-loop", 0, {"duration_s": "5", "speed_profile": "random"})
    _, estimate = _run(
        SmootherBatch,
        SmootherBatch.Config(velocity_walk_m_s_sqrt_s=[0.02, 0.0]),
        sequence,
    )
    events = [e for e in estimate.diagnostics.events if e.kind == "factorization_fallback"]
    assert any(e.details.get("to") == "dense QR" for e in events)
    assert any("dense QR" in note for note in estimate.notes)
    covariances = estimate.smoothed.pose.covariances
    assert np.all(np.isfinite(covariances)) and np.all(np.linalg.eigvalsh(covariances) > 0)


def test_keeping_the_newest_keyframe_in_the_root_changes_no_estimate(rover_isam2, monkeypatch):
    """The root-clique ordering (``smoothers.backends.eliminated_last``) against GTSAM's
    default order (no constraints given): the same causal and smoothed states, covariances,
    map and NIS, to round-off (measured: 2.3e-9 of the largest entry at most, in a gyro-bias
    covariance; the order changes GTSAM's elimination path, as ``ROUND_OFF`` says)."""
    _, ordered = rover_isam2
    monkeypatch.setattr(backends, "eliminated_last", lambda keys: None)
    sequence = load_dataset("sim:aghili-rover", 2, {"duration_s": "3"})
    _, default = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)
    for history in ("causal", "smoothed"):
        a, b = getattr(ordered, history), getattr(default, history)
        assert _difference(a.pose.positions, b.pose.positions) < 1e-9
        assert (
            _difference(a.pose.covariances, b.pose.covariances)
            < 1e-7 * np.abs(b.pose.covariances).max()
        )
        for name, block in b.blocks.items():
            assert _difference(a.blocks[name].values, block.values) < 1e-9
            scale = np.abs(block.covariances).max()
            assert _difference(a.blocks[name].covariances, block.covariances) < 1e-7 * scale
    assert _difference(ordered.landmarks.positions, default.landmarks.positions) < 1e-9
    assert len(ordered.diagnostics.scan_nis) == len(default.diagnostics.scan_nis) > 10
    assert _difference(ordered.diagnostics.scan_nis, default.diagnostics.scan_nis) < 1e-6
