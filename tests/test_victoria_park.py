"""Victoria Park loader (gtsam wheel's Data/victoria_park.txt): format, nominal time, bad input,
and a short ekf-slam run on it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.measurements import GyroSample, LandmarkScan, Odometry
from datasets.victoria_park import (
    VICTORIA_PARK_ODOMETRY,
    VictoriaParkOptions,
    default_path,
    load,
    load_file,
    read_file,
)


@pytest.fixture(scope="module")
def full():
    if not default_path().is_file():
        pytest.skip(f"gtsam's victoria_park.txt absent (expected at {default_path()})")
    sequence = load(None, 0, {})
    return sequence, list(sequence.measurements())


def test_file_contents_as_documented(full) -> None:
    sequence, stream = full
    meta = sequence.metadata
    assert (meta["steps"], meta["sightings"], meta["landmarks"], meta["scans"]) == (
        6968,
        3640,
        151,
        3331,
    )
    assert meta["landmarks_seen_once"] == 28
    assert 3900 < meta["path_length_m"] < 4100
    assert sequence.ground_truth.pose is None and sequence.ground_truth.landmarks is None
    assert len(sequence.ground_truth.scan_ids) == 3331


def test_stream_order_nominal_time_and_gyro_rate(full) -> None:
    sequence, stream = full
    step = sequence.metadata["step_s"]
    assert step == 0.2
    times = np.array([m.t for m in stream])
    assert np.all(np.diff(times) >= 0)
    odometry = [m for m in stream if isinstance(m, Odometry)]
    gyro = [m for m in stream if isinstance(m, GyroSample)]
    assert len(odometry) == len(gyro) == 6968
    np.testing.assert_allclose([m.t for m in odometry], step * np.arange(1, 6969))
    for g, o in zip(gyro[:50], odometry[:50]):
        assert g.t == o.t and g.rate.shape == (1,)
        assert g.rate[0] == pytest.approx(o.relative_pose[2] / step)
        assert o.dt == step and o.velocity is None
    # default: the calibrated model (the file's covariance is optimistic); 'file' keeps it
    np.testing.assert_allclose(
        odometry[0].covariance,
        VICTORIA_PARK_ODOMETRY.increment_covariance(odometry[0].relative_pose, step),
    )
    as_in_file = load(None, 0, {"odometry_noise": "file", "max_steps": "5"})
    first = next(m for m in as_in_file.measurements() if isinstance(m, Odometry))
    np.testing.assert_allclose(first.covariance, np.diag([1e-4, 4e-6, 4e-6]))
    # the first sighting (pose 4, landmark 5 at (11.5387, -3.2007)) comes right after the 4th odometry step
    first_scan = next(i for i, m in enumerate(stream) if isinstance(m, LandmarkScan))
    scan = stream[first_scan]
    assert scan.t == pytest.approx(4 * step) and isinstance(stream[first_scan - 1], Odometry)
    np.testing.assert_allclose(scan.points[0], [11.5387, -3.2007])
    np.testing.assert_allclose(scan.covariances[0], np.eye(2) * 0.4)
    assert list(scan.ids) == [5]


def test_ids_withheld_and_step_option() -> None:
    if not default_path().is_file():
        pytest.skip("gtsam's victoria_park.txt absent")
    sequence = load(None, 0, {"ids": "false", "step_s": "0.1", "max_steps": "200"})
    scans = [m for m in sequence.measurements() if isinstance(m, LandmarkScan)]
    assert scans and all(scan.ids is None for scan in scans)
    assert sequence.metadata["steps"] == 200
    assert max(m.t for m in sequence.measurements()) == pytest.approx(20.0)
    with pytest.raises(InputError, match="known keys"):
        load(None, 0, {"stepsize": "1"})


def write(tmp_path: Path, lines: list[str]) -> Path:
    path = tmp_path / "vp.txt"
    path.write_text("\n".join(lines) + "\n")
    return path


GOOD_ODOMETRY = "ODOMETRY 0 1 0.5 0 0.01 0.0001 0 0 4e-06 0 4e-06"


def test_truncated_line_names_file_and_line(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        [
            GOOD_ODOMETRY,
            "LANDMARK 1 2 10.0 -3.0 0.4 0",
            "ODOMETRY 1 3 0.5 0 0.01 0.0001 0 0 4e-06 0 4e-06",
        ],
    )
    with pytest.raises(InputError, match=r"vp\.txt:2: LANDMARK needs 7 fields"):
        read_file(path)


def test_malformed_number_unknown_tag_and_broken_chain(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"vp\.txt:1: malformed number"):
        read_file(write(tmp_path, ["ODOMETRY 0 1 0.5 0 zero 0.0001 0 0 4e-06 0 4e-06"]))
    with pytest.raises(InputError, match=r"vp\.txt:2: unknown tag 'POSE'"):
        read_file(write(tmp_path, [GOOD_ODOMETRY, "POSE 1 0 0 0"]))
    with pytest.raises(
        InputError, match=r"vp\.txt:2: landmark seen from pose 0 but the last pose is 1"
    ):
        read_file(write(tmp_path, [GOOD_ODOMETRY, "LANDMARK 0 2 10.0 -3.0 0.4 0 0.4"]))
    with pytest.raises(InputError, match=r"vp\.txt:2: odometry starts from pose 5"):
        read_file(
            write(tmp_path, [GOOD_ODOMETRY, "ODOMETRY 5 6 0.5 0 0.01 0.0001 0 0 4e-06 0 4e-06"])
        )
    with pytest.raises(InputError, match="not positive definite"):
        read_file(write(tmp_path, ["ODOMETRY 0 1 0.5 0 0.01 0.0001 0 0 0 0 4e-06"]))


def test_small_file_round_trip(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        [
            GOOD_ODOMETRY,
            "LANDMARK 1 2 10.0 -3.0 0.4 0.1 0.5",
            "LANDMARK 1 3 5.0 2.0 0.4 0 0.4",
            "ODOMETRY 1 4 0.6 0.01 -0.02 0.0001 0 0 4e-06 0 4e-06",
            "LANDMARK 4 2 9.4 -3.0 0.4 0 0.4",
        ],
    )
    sequence = load_file(path, VictoriaParkOptions(step_s=0.5))
    stream = list(sequence.measurements())
    kinds = [type(m).__name__ for m in stream]
    assert kinds == [
        "GyroSample",
        "Odometry",
        "LandmarkScan",
        "GyroSample",
        "Odometry",
        "LandmarkScan",
    ]
    first = stream[2]
    assert first.t == 0.5 and list(first.ids) == [2, 3]
    np.testing.assert_allclose(first.covariances[0], [[0.4, 0.1], [0.1, 0.5]])
    assert stream[3].rate[0] == pytest.approx(-0.02 / 0.5)
    assert sequence.metadata["landmarks_seen_once"] == 1


def test_ekf_slam_on_the_first_1000_steps_with_ids() -> None:
    if not default_path().is_file():
        pytest.skip("gtsam's victoria_park.txt absent")
    from filters.ekf_slam.config import EkfSlamConfig
    from filters.ekf_slam.filter import EkfSlam

    sequence = load(None, 0, {"max_steps": "1000"})
    estimator = EkfSlam(EkfSlamConfig(), sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    estimate = estimator.estimate()
    seen = {int(i) for _, ids in sequence.ground_truth.scan_ids for i in ids}
    assert len(estimate.landmarks) == len(seen)
    nis = estimate.diagnostics.nis
    assert (
        len(nis) > 100 and 0.1 < nis.mean() < 2.0
    )  # 2 dof; the file's 0.4 m^2 is generous (GTSAM says so too)
    assert estimate.causal.pose.t[-1] == pytest.approx(1000 * 0.2)
