"""UTIAS MRCLAM loader: time recovery, quirks counted, swapped labels, covariances, bad input.

Real-data tests read ../shared/data/utias-mrclam1 beside the clone and skip when it is
absent; the bad-input and printed-time tests write small MRCLAM folders into tmp_path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.measurements import GyroSample, LandmarkScan, Odometry
from datasets.range_bearing import convert
from datasets.rotations import rot2, wrap_angle
from datasets.utias import (
    UtiasOptions,
    grid_times,
    load,
    load_mrclam,
    read_table,
    repair_heading_glitches,
)

UTIAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "utias-mrclam1"
needs_data = pytest.mark.skipif(
    not UTIAS.is_dir(), reason=f"UTIAS MRCLAM data absent (expected at {UTIAS})"
)


# tiny folders have too little Vicon for the fits at load: white noise, the commanded velocities
# the synthetic folders are too short to fit anything against their truth
RAW_ODOMETRY = dict(
    odometry_noise="white",
    odometry_speed_scale=1.0,
    odometry_turn_scale=1.0,
    odometry_speed_turn_coupling=0.0,
    sighting_correlation="none",
)


QUICK_FITS = {
    "odometry_noise": "white",
    "sighting_correlation": "none",
    "detection_probability": "none",
}
"""Options that leave out the fits a test does not look at (each load with options of its
own fits again: about 5 s with all four, 1 s with the odometry calibration alone)."""


@pytest.fixture(scope="module")
def robot1():
    if not UTIAS.is_dir():
        pytest.skip(f"UTIAS MRCLAM data absent (expected at {UTIAS})")
    sequence = load(f"{UTIAS}#robot1", 0, {})
    return sequence, list(sequence.measurements())


# ---------------------------------------------------------------- pure helpers
def test_grid_times_accept_rounded_printing_and_reject_irregular_rows() -> None:
    printed = np.array(
        [999.96, 999.98, 1000.0, 1000.0, 1000.0, 1000.1, 1000.1, 1000.1, 1000.1, 1000.1, 1000.2]
    )
    recovered = grid_times(printed, 0.02)
    assert recovered is not None
    np.testing.assert_allclose(np.diff(recovered), 0.02)
    assert grid_times(np.array([0.0, 0.02, 0.05, 0.06]), 0.02) is None


def test_heading_glitch_runs_are_replaced_by_the_short_way_round() -> None:
    heading = np.array(
        [3.12, 3.13, 3.14, -1.72, 2.33, 3.138, -3.14, -3.13]
    )  # a 2-sample glitch, then a real wrap
    repaired, count = repair_heading_glitches(heading, 0.02, 3.0)
    assert count == 2
    assert np.all(np.abs(wrap_angle(np.diff(repaired))) < 0.05)
    np.testing.assert_allclose(repaired[[0, 1, 2, 5, 6, 7]], heading[[0, 1, 2, 5, 6, 7]])


def test_range_bearing_covariance_matches_monte_carlo() -> None:
    rng = np.random.default_rng(0)
    r, b, sr, sb = 3.0, 0.6, 0.05, 0.01
    points, cov = convert(np.array([r]), np.array([b]), np.array([sr]), sb, "first-order")
    np.testing.assert_allclose(points[0], [r * np.cos(b), r * np.sin(b)])
    samples = rng.normal([r, b], [sr, sb], size=(200_000, 2))
    cloud = np.stack(
        [samples[:, 0] * np.cos(samples[:, 1]), samples[:, 0] * np.sin(samples[:, 1])], -1
    )
    np.testing.assert_allclose(np.cov(cloud.T), cov[0], rtol=0.02, atol=1e-7)


# ---------------------------------------------------------------- real data
@needs_data
def test_robot1_stream_times_and_kinds(robot1) -> None:
    sequence, stream = robot1
    assert sequence.metadata["time_source"] == "row_grid"
    gyro_t = np.array([m.t for m in stream if isinstance(m, GyroSample)])
    odometry = [m for m in stream if isinstance(m, Odometry)]
    assert len(gyro_t) == len(odometry) == 75000
    np.testing.assert_allclose(
        np.diff(gyro_t), 0.02, atol=1e-9
    )  # also after 1000 s, where the file rounds to 0.1 s
    assert all(m.velocity is not None and m.velocity.shape == (2,) for m in odometry[:100])
    times = np.array([m.t for m in stream])
    assert np.all(np.diff(times) >= 0)
    gyro = next(m for m in stream if isinstance(m, GyroSample) and m.t > 100)
    odo = next(m for m in odometry if m.t == gyro.t)
    assert gyro.rate.shape == (1,) and gyro.rate[0] == odo.velocity[1]


@needs_data
def test_robot1_quirks_are_counted(robot1) -> None:
    sequence, stream = robot1
    counts = sequence.counts
    assert counts["robot_barcodes"] > 500  # other robots are seen often
    assert 0 < counts["stale_repeats"] < 200
    assert counts["vicon_heading_samples_repaired"] > 0
    scans = [m for m in stream if isinstance(m, LandmarkScan)]
    robot_barcodes = {5, 14, 41, 32, 23}
    assert not robot_barcodes & set(np.concatenate([s.ids for s in scans]).tolist())
    truth = sequence.ground_truth
    rates = np.abs(wrap_angle(np.diff(truth.pose.rotations))) / np.diff(truth.pose.t)
    assert rates.max() < 3.0  # no glitch left (the robot turns at most 0.57 rad/s commanded)
    assert len(truth.scan_ids) == len(scans)


@needs_data
def test_initial_state_is_the_first_vicon_pose(robot1) -> None:
    sequence, _ = robot1
    truth = sequence.ground_truth.pose
    np.testing.assert_allclose(sequence.initial_state.position, truth.positions[0])
    assert float(sequence.initial_state.rotation) == pytest.approx(truth.rotations[0])


def _mean_world_sighting(sequence, stream, barcode: int) -> np.ndarray:
    pose = sequence.ground_truth.pose
    world = []
    for scan in stream:
        if isinstance(scan, LandmarkScan) and barcode in scan.ids:
            i = min(np.searchsorted(pose.t, scan.t), len(pose.t) - 1)
            point = scan.points[list(scan.ids).index(barcode)]
            world.append(pose.positions[i] + rot2(pose.rotations[i]) @ point)
    return np.median(np.array(world), axis=0)


@needs_data
def test_swapped_labels_18_and_61_are_fixed_by_default(robot1) -> None:
    sequence, stream = robot1
    fixed = sequence.ground_truth.landmarks
    # the survey as filed; the fits that do not bear on it left out (they take the time)
    as_filed = load(
        f"{UTIAS}#robot1", 0, {"fix_swapped_labels": "false", "duration_s": "10", **QUICK_FITS}
    ).ground_truth.landmarks
    for barcode in (18, 61):
        seen = _mean_world_sighting(sequence, stream, barcode)
        assert np.linalg.norm(fixed.positions[list(fixed.ids).index(barcode)] - seen) < 0.1
        assert np.linalg.norm(as_filed.positions[list(as_filed.ids).index(barcode)] - seen) > 1.0
    # every other landmark agrees with the survey either way
    for barcode in (9, 25, 54, 90):
        seen = _mean_world_sighting(sequence, stream, barcode)
        assert np.linalg.norm(as_filed.positions[list(as_filed.ids).index(barcode)] - seen) < 0.1


@needs_data
def test_ids_can_be_withheld_and_options_checked() -> None:
    sequence = load(f"{UTIAS}#robot1", 0, {"ids": "false", "duration_s": "60"})
    scans = [m for m in sequence.measurements() if isinstance(m, LandmarkScan)]
    assert scans and all(scan.ids is None for scan in scans)
    assert len(sequence.ground_truth.scan_ids) == len(scans)
    assert sequence.ground_truth.pose.t[-1] <= 60.0
    # sightings after duration_s are not selected, which is not a drop (no warning)
    assert sequence.counts["out_of_range_times"] == 0
    with pytest.raises(InputError, match="known keys"):
        load(f"{UTIAS}#robot1", 0, {"idz": "false"})
    with pytest.raises(InputError, match="robotN"):
        load(f"{UTIAS}#rover1", 0, {})
    with pytest.raises(InputError, match="does not exist"):
        load("/nonexistent/folder#robot1", 0, {})


# ---------------------------------------------------------------- small synthetic folders
def write_folder(
    folder: Path, odometry: list[str], measurements: list[str], truth: list[str] | None = None
) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "Barcodes.dat").write_text(
        "# Subject # Barcode #\n1 5\n2 14\n3 41\n4 32\n5 23\n6 72\n7 27\n"
    )
    (folder / "Landmark_Groundtruth.dat").write_text(
        "# s x y sx sy\n6 1.0 2.0 0.001 0.001\n7 3.0 -1.0 0.001 0.001\n"
    )
    (folder / "Robot1_Odometry.dat").write_text("\n".join(odometry) + "\n")
    (folder / "Robot1_Measurement.dat").write_text("\n".join(measurements) + "\n")
    truth = truth or [f"{line.split()[0]} 0.0 0.0 0.0" for line in odometry]
    (folder / "Robot1_Groundtruth.dat").write_text("\n".join(truth) + "\n")
    return folder


def grid_odometry(rows: int) -> list[str]:
    return [f"{0.02 * i:.5g} 0.1 0.0" for i in range(rows)]


def test_truncated_measurement_file_names_file_and_line(tmp_path: Path) -> None:
    folder = write_folder(
        tmp_path / "d",
        grid_odometry(50),
        ["# time barcode range bearing", "0.1 72 2.0 0.1", "0.2 27 3.0"],
    )
    with pytest.raises(InputError, match=r"Robot1_Measurement\.dat:3: expected 4 columns"):
        load_mrclam(folder, 1, UtiasOptions())


def test_malformed_number_names_file_and_line(tmp_path: Path) -> None:
    odometry = grid_odometry(10)
    odometry[6] = "0.12 0.1 x"
    folder = write_folder(tmp_path / "d", odometry, ["0.1 72 2.0 0.1"])
    with pytest.raises(InputError, match=r"Robot1_Odometry\.dat:7: not a number"):
        load_mrclam(folder, 1, UtiasOptions())


def test_unknown_robot_duplicate_and_out_of_range_sightings_are_dropped_and_counted(
    tmp_path: Path,
) -> None:
    sightings = [
        "0.10 72 2.0 0.1",
        "0.10 72 2.1 0.1",  # same barcode twice at one time
        "0.12 99 2.0 0.1",  # unknown barcode
        "0.14 14 1.0 0.0",  # another robot
        "0.20 27 3.0 -0.2",
        "0.30 27 3.0 -0.2",  # stale repeat
        "0.40 72 1.9 0.12",
        "5.00 72 1.9 0.12",  # after the last odometry row
    ]
    folder = write_folder(tmp_path / "d", grid_odometry(50), sightings)
    options = dict(ids=True, landmark_conversion="first-order", **RAW_ODOMETRY)
    # one unknown barcode in 8 sightings is beyond the default 1 % (a Barcodes.dat of
    # another dataset): accepted explicitly here, to count it
    with pytest.raises(InputError, match="1 of 8 sightings name barcodes"):
        load_mrclam(folder, 1, UtiasOptions(**options))
    options["max_dropped_fraction"] = 0.2
    # a sighting after the last odometry row is an edge, trimmed and said, never an error
    sequence = load_mrclam(folder, 1, UtiasOptions(**options))
    assert any(
        "1 of 8 sightings lie outside the odometry's time span" in line and "trimmed" in line
        for line in sequence.all_warnings()
    )
    counts = sequence.counts
    assert counts["duplicate_sightings"] == 1
    assert counts["unknown_barcodes"] == 1
    assert counts["robot_barcodes"] == 1
    assert counts["stale_repeats"] == 1
    assert counts["out_of_range_times"] == 1
    scans = [m for m in sequence.measurements() if isinstance(m, LandmarkScan)]
    assert [list(scan.ids) for scan in scans] == [[72], [27], [72]]
    np.testing.assert_allclose(scans[0].points[0], [2.0 * np.cos(0.1), 2.0 * np.sin(0.1)])
    sigma_r = max(0.05, 0.05 * 2.0)
    assert np.trace(scans[0].covariances[0]) == pytest.approx(sigma_r**2 + (2.0 * 0.03) ** 2)


def test_sightings_going_back_in_time_inside_the_span_are_an_error(tmp_path: Path) -> None:
    sightings = ["0.10 72 2.0 0.1", "0.30 27 3.0 -0.2", "0.20 72 1.9 0.12", "0.40 27 3.1 -0.2"]
    folder = write_folder(tmp_path / "d", grid_odometry(50), sightings)
    with pytest.raises(InputError, match=r"1 of 4 sightings go back in time"):
        load_mrclam(folder, 1, UtiasOptions(**RAW_ODOMETRY))
    accepted = load_mrclam(folder, 1, UtiasOptions(**RAW_ODOMETRY, max_dropped_fraction=0.3))
    assert accepted.counts["time_going_back"] == 1


def test_the_workbench_run_of_a_trimmed_edge_exits_0_with_the_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from workbench.cli import main

    sightings = ["0.10 72 2.0 0.1", "0.40 72 1.9 0.12", "5.00 72 1.9 0.12", "6.00 27 3.0 0.1"]
    folder = write_folder(tmp_path / "d", grid_odometry(50), sightings)
    data = [f"{key}={value}" for key, value in RAW_ODOMETRY.items()]
    argv = ["run", "dead-reckoning", f"utias:{folder}#robot1", "--no-plots"]
    argv += [item for pair in zip(["--data"] * len(data), data) for item in pair]
    assert main([*argv, "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "2 of 4 sightings lie outside" in err and "trimmed" in err


def test_irregular_printed_times_gap_and_duplicate_rows(tmp_path: Path) -> None:
    # an original (not resampled) MRCLAM log: unix-like times, a duplicate row, a 2 s gap
    base = 1248272272.0
    times = (
        [base + 0.015 * i for i in range(20)]
        + [base + 0.015 * 19]
        + [base + 2.5 + 0.015 * i for i in range(10)]
    )
    odometry = [f"{t:.3f} 0.2 0.1" for t in times]
    folder = write_folder(tmp_path / "d", odometry, [f"{base + 0.1:.3f} 72 2.0 0.1"])
    # one dropped row of 31 here: accepted explicitly (the default 1 % would refuse it)
    options = UtiasOptions(**RAW_ODOMETRY, max_dropped_fraction=0.05)
    sequence = load_mrclam(folder, 1, options)
    assert sequence.metadata["time_source"] == "printed"
    assert sequence.counts["odometry_time_not_increasing"] == 1
    gaps = sequence.metadata["odometry_gaps"]
    assert len(gaps) == 1 and gaps[0][1] == pytest.approx(2.5 - 0.015 * 19, abs=1e-3)
    stream = list(sequence.measurements())
    assert stream[0].t == pytest.approx(0.0)
    assert sum(isinstance(m, Odometry) for m in stream) == 30
    with pytest.raises(InputError, match=r"do not increase in time .*Robot1_Odometry\.dat:\d+"):
        load_mrclam(folder, 1, UtiasOptions(**RAW_ODOMETRY))


def test_a_vicon_glitch_is_excluded_from_the_scoring_and_from_the_fits(tmp_path: Path) -> None:
    """A marker swap (the track 3 m off for four samples) is found by the truth-quality
    detector, listed, warned and scored nowhere; the truth keeps its samples but the
    metrics leave them out (``GroundTruth.excluded``)."""
    odometry = [f"{0.02 * i:.5g} 0.2 0.0" for i in range(400)]
    truth = [f"{0.02 * i:.5g} {0.004 * i:.5f} 0.0 0.0" for i in range(400)]
    for i in range(200, 204):
        t, x, y, h = truth[i].split()
        truth[i] = f"{t} {float(x) + 3.0:.5f} {y} {h}"
    folder = write_folder(tmp_path / "d", odometry, ["0.10 72 2.0 0.1"], truth)
    sequence = load_mrclam(folder, 1, UtiasOptions(**RAW_ODOMETRY))
    assert sequence.counts["vicon_samples_excluded"] == 4
    assert sequence.excluded_truth_s == pytest.approx(3 * 0.02)
    (line,) = sequence.metadata["excluded_truth"]
    assert line.startswith("wrong_track") and "4.000" in line and "4.060" in line
    assert any("Vicon not trusted in 1 interval" in w for w in sequence.all_warnings())
    truth_t = sequence.ground_truth.pose.t
    trusted = sequence.ground_truth.trusted(truth_t)
    assert np.array_equal(np.flatnonzero(~trusted), np.arange(200, 204))


def test_label_swaps_are_detected_from_the_sightings_not_assumed() -> None:
    from datasets.utias import detect_label_swaps

    truth_t = np.arange(50) * 0.1
    truth_xy = np.zeros((50, 2))
    heading = np.zeros(50)
    surveyed = {11: np.array([2.0, 0.0]), 17: np.array([0.0, 3.0]), 12: np.array([-2.0, 1.0])}
    subject_of = {18: 11, 61: 17, 9: 12}
    # barcode 18 is seen where subject 17 stands, 61 where 11 stands, 9 where it should be
    scans = [
        LandmarkScan(
            t=float(t),
            points=np.array([[0.0, 3.0], [2.0, 0.0], [-2.0, 1.0]]),
            covariances=np.repeat(np.eye(2)[None] * 0.01, 3, axis=0),
            ids=np.array([18, 61, 9]),
        )
        for t in truth_t
    ]
    assert detect_label_swaps(scans, truth_t, truth_xy, heading, subject_of, surveyed) == [(18, 61)]
    honest = [
        LandmarkScan(t=s.t, points=s.points[[1, 0, 2]], covariances=s.covariances, ids=s.ids)
        for s in scans
    ]
    assert detect_label_swaps(honest, truth_t, truth_xy, heading, subject_of, surveyed) == []


@needs_data
def test_detection_probability_is_fitted_by_range_against_vicon(robot1) -> None:
    """The camera sights a barcode in view far more often near than far (robots 2-5, the
    fit robot 1 gets: about 0.6 within 1-3 m, under 0.17 beyond 6 m): one P_D for all
    ranges would misprice both."""
    sequence, _ = robot1
    model = sequence.noise.landmark_detection
    assert model is not None and "Vicon" in model.source
    assert "not the scored robot 1" in model.source  # cross-validated by default
    near = model.at(np.array([1.5, 2.5]))
    far = model.at(np.array([6.5, 7.5]))
    # pooled over robots 2-5 (dataset 1: 0.5-0.8 within 3 m, 0.14-0.26 beyond 5 m per robot)
    assert np.all((near > 0.55) & (near < 0.85)) and np.all(far < 0.25)
    assert near.min() > 2.5 * far.max()
    assert sequence.metadata["detection_probability"]["counts"] == list(model.counts)
    unfitted = load(
        f"{UTIAS}#robot1", 0, {**QUICK_FITS, "duration_s": "10", "detection_probability": "none"}
    )
    assert unfitted.noise.landmark_detection is None


def test_read_table_converts_once_and_still_names_the_bad_line(tmp_path: Path) -> None:
    # the whole table goes through one numpy conversion; a value it cannot take is looked
    # up row by row, so a bad row is still named by its line, and what Python's float()
    # reads (numpy does not: "2_0") is read as before
    table = tmp_path / "Robot1_Odometry.dat"
    table.write_text("# time v omega\n1.25 0.5 2_0\n\n1.5 0.5 -0.1  # comment\n")
    read = read_table(table, ("time", "v", "omega"))
    np.testing.assert_array_equal(read.values, [[1.25, 0.5, 20.0], [1.5, 0.5, -0.1]])
    np.testing.assert_array_equal(read.lines, [2, 4])
    np.testing.assert_array_equal(read.first_decimals, [2, 1])
    table.write_text("1.0 0.5 0.1\n2.0 0.5 nan\n")
    with pytest.raises(InputError, match=r"Robot1_Odometry.dat:2: non-finite value"):
        read_table(table, ("time", "v", "omega"))
    table.write_text("1.0 0.5 0.1\n2.0 fast 0.1\n")
    with pytest.raises(InputError, match=r"Robot1_Odometry.dat:2: not a number"):
        read_table(table, ("time", "v", "omega"))


def test_read_table_fast_path_is_bit_identical_to_reading_row_by_row(tmp_path: Path) -> None:
    # pandas' C parser reads a clean file; with round-trip precision every value is the
    # double Python's float() gives, and lines and printed decimals are those of the rows
    from datasets.utias.tables import _read_table_checked

    rng = np.random.default_rng(0)
    rows = [f"{0.02 * k:.2f} {rng.normal():.17g} {rng.normal() * 1e-7:.6e}" for k in range(2000)]
    rows[5] = "# a comment line"
    rows[9] = ""
    rows[12] = "   \t"
    rows[20] = "+0.4 -0.0 1E+2  # trailing comment"
    table = tmp_path / "Robot1_Odometry.dat"
    table.write_text("\n".join(rows) + "\n")
    fast = read_table(table, ("time", "v", "omega"))
    checked = _read_table_checked(table, ("time", "v", "omega"))
    assert fast.values.tobytes() == checked.values.tobytes()
    np.testing.assert_array_equal(fast.lines, checked.lines)
    np.testing.assert_array_equal(fast.first_decimals, checked.first_decimals)
    assert len(fast.values) == 1997 and fast.lines[5] == 7
    table.write_text("1.0 0.5 0.1\n2.0 0.5\n")
    with pytest.raises(InputError, match=r"Robot1_Odometry.dat:2: expected 3 columns"):
        read_table(table, ("time", "v", "omega"))
    table.write_text("1.0 0.5 0.1\n2.0 0.5 0.1 7\n")
    with pytest.raises(InputError, match=r"Robot1_Odometry.dat:2: expected 3 columns"):
        read_table(table, ("time", "v", "omega"))


# ---------------------------------------------------------------- calibration source
def test_a_folder_with_one_robot_fits_nothing_and_says_so(tmp_path: Path) -> None:
    folder = write_folder(tmp_path / "d", grid_odometry(50), ["0.10 72 2.0 0.1"])
    sequence = load_mrclam(folder, 1, UtiasOptions(odometry_noise="white"))
    assert sequence.calibration.startswith("none")
    assert any("holds no other robot" in line for line in sequence.all_warnings())
    assert sequence.metadata["odometry_scales"]["turn"] == 1.0
    assert sequence.noise.sighting_correlation is None


@needs_data
def test_the_default_calibration_never_sees_the_scored_robots_truth(tmp_path: Path) -> None:
    """Robot 1's Vicon corrupted (every position after 300 s moved 0.5 m): its default
    calibration, fitted on robots 2-5, is unchanged to the last bit; the own-truth fit (kept
    as an option, tuning on the test set) moves."""
    folder = tmp_path / "mrclam"
    folder.mkdir()
    for path in UTIAS.iterdir():
        if path.name != "Robot1_Groundtruth.dat":
            (folder / path.name).symlink_to(path)
    rows = []
    for line in (UTIAS / "Robot1_Groundtruth.dat").read_text().splitlines():
        fields = line.split()
        if line.startswith("#") or len(fields) != 4 or float(fields[0]) < 300.0:
            rows.append(line)
        else:
            rows.append(f"{fields[0]} {float(fields[1]) + 0.5:.3f} {fields[2]} {fields[3]}")
    (folder / "Robot1_Groundtruth.dat").write_text("\n".join(rows) + "\n")
    # the odometry calibration alone (the other fits take the same source, and time)
    options = {
        "duration_s": "60",
        "odometry_noise": "white",
        "sighting_correlation": "none",
        "detection_probability": "none",
    }
    original = load(f"{UTIAS}#robot1", 0, options)
    corrupted = load(f"{folder}#robot1", 0, options)
    assert "not the scored robot 1" in corrupted.calibration
    for key in ("speed", "turn", "coupling"):
        assert (
            corrupted.metadata["odometry_scales"][key] == original.metadata["odometry_scales"][key]
        )
    own = {**options, "calibration": "own-truth"}
    assert "own Vicon" in load(f"{folder}#robot1", 0, own).calibration
    assert (
        load(f"{folder}#robot1", 0, own).metadata["odometry_scales"]["speed"]
        != load(f"{UTIAS}#robot1", 0, own).metadata["odometry_scales"]["speed"]
    )
