"""Bad input to the smoother: clear ``InputError``s or documented handling, never an opaque
GTSAM crash."""

from __future__ import annotations

from dataclasses import replace

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import X

from datasets.errors import InputError
from datasets.measurements import ImuSample, LandmarkScan
from smoothers.backends import Isam2Backend
from smoothers.modes import SmootherIsam2
from workbench.registry import load_dataset


@pytest.fixture(scope="module")
def rover():
    return load_dataset("sim:aghili-rover", 1, {"duration_s": "4"})


def _with_stream(sequence, transform):
    items = list(sequence.measurements())
    changed = transform(items)
    return replace(sequence, stream=lambda: iter(changed))


def _run(sequence, **config):
    estimator = SmootherIsam2(SmootherIsam2.Config(**config), sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    return estimator, estimator.estimate()


def test_imu_gap_longer_than_the_threshold_is_an_input_error_naming_the_time(rover):
    gapped = _with_stream(
        rover,
        lambda items: [m for m in items if not (isinstance(m, ImuSample) and 1.0 < m.t < 2.0)],
    )
    with pytest.raises(InputError, match=r"IMU gap: no sample between t=1\.000000 s"):
        _run(gapped, max_gap_s=0.5)


def test_duplicate_time_stamps_are_merged_or_skipped(rover):
    def duplicate(items):
        out = []
        for m in items:
            out.append(m)
            if isinstance(m, (ImuSample, LandmarkScan)) and 1.0 <= m.t <= 1.5:
                out.append(m)  # the same sample or scan twice
        return out

    estimator, estimate = _run(_with_stream(rover, duplicate))
    reference, _ = _run(rover)
    # One keyframe per distinct scan time: the repeated scans share theirs.
    assert estimator.keyframe_t == reference.keyframe_t
    skipped = [e for e in estimate.diagnostics.events if e.kind == "duplicate_imu_sample_skipped"]
    assert len(skipped) > 0


def test_time_going_backwards_is_an_input_error(rover):
    def swap(items):
        items = list(items)
        i = next(i for i in range(10, len(items) - 1) if items[i].t < items[i + 1].t)
        items[i], items[i + 1] = items[i + 1], items[i]
        return items

    with pytest.raises(InputError, match="backwards"):
        _run(_with_stream(rover, swap))


def test_landmark_seen_once_mid_run_is_mapped_with_a_sensible_covariance(rover):
    lonely_id = 99_999

    def add_lonely(items):
        out = []
        done = False
        for m in items:
            if isinstance(m, LandmarkScan) and m.t >= 2.0 and not done:
                point = np.array([[3.0, 1.0, 0.5]])
                m = replace(
                    m,
                    points=np.vstack([m.points, point]),
                    covariances=np.concatenate([m.covariances, np.eye(3)[None] * 0.04]),
                    ids=np.r_[m.ids, lonely_id],
                )
                done = True
            out.append(m)
        return out

    _, estimate = _run(_with_stream(rover, add_lonely))
    index = int(np.flatnonzero(estimate.landmarks.ids == lonely_id)[0])
    covariance = estimate.landmarks.covariances[index]
    eigenvalues = np.linalg.eigvalsh(covariance)
    # One observation of a 3-D point determines it: measurement noise plus pose uncertainty.
    assert np.all(eigenvalues > 0.04 * 0.99) and np.all(eigenvalues < 1.0)


def test_no_initial_state_is_an_indeterminate_system_input_error(rover):
    with pytest.raises(InputError, match="indeterminate"):
        SmootherIsam2(SmootherIsam2.Config(), replace(rover, initial_state=None))


def test_gtsam_indeterminate_system_becomes_an_input_error():
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
    with pytest.raises(InputError, match=r"indeterminate.*|failed inside GTSAM"):
        backend.update(graph, values, {}, 3.5)


def test_missing_imu_noise_and_too_many_anchors_are_input_errors(rover):
    with pytest.raises(InputError, match="noise densities"):
        SmootherIsam2(
            SmootherIsam2.Config(),
            replace(rover, noise=replace(rover.noise, accel_noise_density=None)),
        )
    with pytest.raises(InputError, match="anchors"):
        SmootherIsam2(SmootherIsam2.Config(anchors=10_000), rover)


def test_malformed_scan_is_an_input_error(rover):
    def corrupt(items):
        out = []
        for m in items:
            if isinstance(m, LandmarkScan) and m.count > 0 and 1.0 < m.t < 1.2:
                m = replace(m, covariances=-m.covariances)
            out.append(m)
        return out

    with pytest.raises(InputError, match="positive definite"):
        _run(_with_stream(rover, corrupt))
