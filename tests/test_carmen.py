"""CARMEN log loader: parsing, time stamps (duplicates, unpadded microseconds, lines that go
back), the laser offset, odometry inside FLASER lines, stale odometry, bad lines."""

from __future__ import annotations

import bz2
from pathlib import Path

import numpy as np
import pytest

from datasets.carmen import load, parse_log
from datasets.carmen.messages import guessed_angle_step_rad
from datasets.carmen.odometry import find_stale_runs, relative_increments, spread_stale
from datasets.carmen.stamps import repair_order, stamp_readings
from datasets.errors import InputError
from datasets.measurements import LandmarkScan, Odometry

HEADER = "# CARMEN Logfile\n# message_name [message contents] ipc_timestamp ipc_hostname logger_timestamp\n"


def flaser(t: str, pose: tuple[float, float, float], ranges: list[float] | None = None) -> str:
    """An FLASER line: 180 ranges (a wall 2 m ahead), the logged pose 1 m off (not truth),
    odometry ``pose``, stamp text ``t``."""
    values = ranges if ranges is not None else [2.0] * 180
    x, y, theta = pose
    return (
        f"FLASER {len(values)} {' '.join(f'{r:.2f}' for r in values)} "
        f"{x + 1:.6f} {y:.6f} {theta:.6f} {x:.6f} {y:.6f} {theta:.6f} {t} host 0.0"
    )


def odom(t: str, pose: tuple[float, float, float]) -> str:
    x, y, theta = pose
    return f"ODOM {x:.6f} {y:.6f} {theta:.6f} 0.0 0.0 0.0 {t} host 0.0"


def write_log(path: Path, lines: list[str], compress: bool = False) -> Path:
    text = HEADER + "\n".join(lines) + "\n"
    if compress:
        path.write_bytes(bz2.compress(text.encode("ascii")))
    else:
        path.write_text(text)
    return path


def moving(count: int, start: float = 100.0, step_s: float = 0.2) -> list[tuple[str, tuple]]:
    """(stamp text, odometry pose) of a robot driving along x at 0.25 m/s."""
    return [(f"{start + k * step_s:.6f}", (0.05 * k, 0.0, 0.0)) for k in range(count)]


def test_beam_spacing_follows_carmen_guesses() -> None:
    assert guessed_angle_step_rad(180) == pytest.approx(np.pi / 180)
    assert guessed_angle_step_rad(361) == pytest.approx(np.pi / 360)
    assert guessed_angle_step_rad(401) == pytest.approx(np.pi / 720)
    assert guessed_angle_step_rad(91) == pytest.approx(np.pi / 90)


def test_flaser_odom_fields_are_the_odometry_and_the_logged_pose_is_ignored(tmp_path) -> None:
    """MIT CSAIL has no ODOM lines: the odometry comes from the FLASER lines' odom fields
    (the logged x y theta, 1 m off here, is never used); bzip2 is read by its magic bytes."""
    lines = [flaser(t, pose) for t, pose in moving(6)]
    path = write_log(tmp_path / "mit.clf.bz2", lines, compress=True)
    sequence = load(str(path), 0, {})
    increments = [m for m in sequence.measurements() if isinstance(m, Odometry)]
    assert len(increments) == 5 and all(m.frame for m in increments)
    np.testing.assert_allclose([m.relative_pose for m in increments], [[0.05, 0.0, 0.0]] * 5)
    np.testing.assert_allclose([m.t for m in increments], 100.0 + 0.2 * np.arange(1, 6))
    assert sequence.initial_state.t == pytest.approx(100.0)
    assert sequence.ground_truth is None and sequence.dimension == 2
    assert any("no ODOM lines" in line for line in sequence.all_warnings())


def test_param_laser_offset_is_the_mounting_else_zero_with_a_note(tmp_path) -> None:
    lines = [flaser(t, pose) for t, pose in moving(3)]
    with_param = write_log(tmp_path / "a.clf", ["PARAM robot_frontlaser_offset -0.04 h 0", *lines])
    sequence = load(str(with_param), 0, {})
    assert sequence.metadata["laser_mounting"] == pytest.approx([-0.04, 0.0, 0.0])
    assert "robot_frontlaser_offset -0.04" in sequence.metadata["laser_mounting_source"]
    without = load(str(write_log(tmp_path / "b.clf", lines)), 0, {})
    assert without.metadata["laser_mounting"] == [0.0, 0.0, 0.0]
    assert any("taken as 0" in line for line in without.all_warnings())
    given = load(str(without_path := tmp_path / "b.clf"), 0, {"laser_offset_m": "0.1"})
    assert given.metadata["laser_mounting"][0] == pytest.approx(0.1) and without_path.exists()


def test_unpadded_microseconds_are_read_back_in_the_file_order() -> None:
    """The Intel log's stamps: 556.099081 written as '556.990810' (microseconds without the
    leading zero, padded at the end)."""
    assert stamp_readings("976053556.990810") == pytest.approx([976053556.990810, 976053556.099081])
    stamps = ["555.549906", "556.990810", "556.993770", "556.100282", "556.113110"]
    repair = repair_order(stamps)
    assert repair.kept.tolist() == [0, 1, 2, 3, 4]
    assert repair.reread.tolist() == [1, 2]
    np.testing.assert_allclose(
        repair.times, [555.549906, 556.099081, 556.099377, 556.100282, 556.11311]
    )
    assert repair.backwards == 1


def test_duplicates_and_unrepairable_lines_are_dropped_and_counted() -> None:
    stamps = ["10.100001", "10.200001", "10.200001", "10.300001", "10.050001", "10.400001"]
    contents = ["a", "b", "b", "c", "d", "e"]
    repair = repair_order(stamps, contents)
    assert repair.duplicates.tolist() == [2] and repair.identical_duplicates == 1
    assert repair.dropped.tolist() == [4]  # no stamp ends in zeros: no other reading
    assert repair.kept.tolist() == [0, 1, 3, 5]
    assert np.all(np.diff(repair.times) > 0)


def test_out_of_order_and_duplicated_lines_are_printed_with_evidence(tmp_path) -> None:
    """Scan 3 at 101.04 s written '101.400000' goes back in time and is read back; a
    duplicated line is dropped; both are counted and printed with the line numbers."""
    stamps = ["100.700000", "100.800000", "100.900000", "101.400000", "101.200000", "101.300000"]
    lines = [flaser(t, (0.05 * k, 0.0, 0.0)) for k, t in enumerate(stamps)]
    lines.insert(5, lines[4])  # a duplicated line
    sequence = load(str(write_log(tmp_path / "c.clf", lines)), 0, {})
    counts = sequence.counts
    assert counts["scan_lines_dropped_duplicate"] == 1
    assert counts["scan_stamps_reread"] == 1 and counts["scan_lines_dropped_out_of_order"] == 0
    text = " ".join(sequence.all_warnings())
    assert "1 of 7 stamps go back in time" in text
    assert "line 6: '101.400000' read as 101.040000" in text  # the header takes two lines
    assert "1 dropped as duplicates" in text and "first at line 8" in text
    times = [m.t for m in sequence.measurements() if isinstance(m, Odometry)]
    np.testing.assert_allclose(times, [100.8, 100.9, 101.04, 101.2, 101.3])


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("FLASER 3 1.0 abc 1.0 0 0 0 0 0 0 5.0 h 0", r"bad\.clf:3: FLASER range field 2 is 'abc'"),
        (
            "FLASER 180 1.0 2.0 3.0",
            r"bad\.clf:3: FLASER has 4 fields after the tag, needs at least",
        ),
        ("FLASER x 1.0", r"bad\.clf:3: FLASER num_readings is 'x', not an integer"),
        ("ODOM 0 0 0 0 0 0 never h 0", r"bad\.clf:3: ODOM ipc_timestamp is 'never'"),
        ("FLASER 2 1.0 nan 0 0 0 0 0 0 5.0 h 0", r"bad\.clf:3: FLASER range field 2 is 'nan'"),
    ],
)
def test_a_bad_line_is_an_input_error_naming_file_and_line(tmp_path, line, message) -> None:
    path = write_log(tmp_path / "bad.clf", [line])
    with pytest.raises(InputError, match=message):
        parse_log(path)


def test_a_log_without_lasers_or_a_missing_file_is_refused(tmp_path) -> None:
    with pytest.raises(InputError, match="no laser lines"):
        parse_log(write_log(tmp_path / "o.clf", [odom("1.0", (0, 0, 0))]))
    with pytest.raises(InputError, match="no such file"):
        load(str(tmp_path / "missing.clf"), 0, {})
    with pytest.raises(InputError, match="needs a log file"):
        load(None, 0, {})
    with pytest.raises(InputError, match="scan_strid"):
        load(
            str(write_log(tmp_path / "p.clf", [flaser("1.0", (0, 0, 0))] * 1)),
            0,
            {"scan_strid": "2"},
        )


def test_odom_lines_are_compared_and_usable_as_the_motion_input(tmp_path) -> None:
    rows = moving(5)
    lines = []
    for t, pose in rows:
        lines.append(odom(t, pose))
        lines.append(flaser(t, pose))
    path = write_log(tmp_path / "d.clf", ["SYNC tag 1 h 0", *lines])
    sequence = load(str(path), 0, {})
    assert any(
        "equals the latest ODOM pose before it at 5 of 5" in w for w in sequence.all_warnings()
    )
    assert sequence.metadata["totals"]["skipped_SYNC"] == 1
    by_messages = load(str(path), 0, {"odometry": "messages"})
    steps = [m.relative_pose for m in by_messages.measurements() if isinstance(m, Odometry)]
    np.testing.assert_allclose(steps, [[0.05, 0.0, 0.0]] * 4, atol=1e-9)


def test_robotlaser1_states_its_geometry_and_mounting(tmp_path) -> None:
    ranges = " ".join(["3.0"] * 5)
    line = (
        f"ROBOTLASER1 0 -1.5708 3.1416 0.7854 81.9 0.01 0 5 {ranges} 0 "
        "1.2 2.0 0.0 1.0 2.0 0.0 0 0 0 0 0 42.0 host 1.0"
    )
    log = parse_log(write_log(tmp_path / "r.clf", [line]))
    message = log.lasers[0]
    assert message.kind == "ROBOTLASER1" and message.angle_step_rad == pytest.approx(0.7854)
    np.testing.assert_allclose(message.mounting, [0.2, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(message.odometry, [1.0, 2.0, 0.0])
    assert message.t == 42.0


def test_rear_laser_faces_back_and_front_lines_are_counted_as_skipped(tmp_path) -> None:
    rows = moving(3)
    lines = [flaser(t, pose).replace("FLASER", "RLASER") for t, pose in rows]
    lines += [flaser(f"{float(t) + 0.05:.6f}", pose) for t, pose in rows]
    path = write_log(tmp_path / "e.clf", ["PARAM robot_rearlaser_offset -0.2 h 0", *lines])
    sequence = load(str(path), 0, {"laser": "rear"})
    assert sequence.metadata["laser_mounting"] == pytest.approx([-0.2, 0.0, np.pi])
    assert sequence.metadata["totals"]["laser_lines_other"] == 3


def test_stale_odometry_is_spread_over_its_run() -> None:
    """MIT CSAIL: the pose stops changing for a few scans while moving at 1 m/s, then jumps."""
    times = np.arange(10) * 0.2
    truth = np.column_stack([0.2 * np.arange(10), np.zeros(10), np.zeros(10)])
    logged = truth.copy()
    logged[4:7] = truth[3]  # scans 4-6 repeat scan 3's pose; scan 7 jumps 0.8 m
    stale = find_stale_runs(times, logged)
    assert stale.runs == ((3, 7),) and stale.scans == 3
    np.testing.assert_allclose(spread_stale(times, logged, stale), truth, atol=1e-12)
    stopped = truth.copy()
    stopped[4:7] = truth[3]
    stopped[7:] = truth[3] + np.array([0.02, 0.0, 0.0]) * np.arange(1, 4)[:, None]
    assert find_stale_runs(times, stopped).runs == ()  # a real stop starts again slowly
    np.testing.assert_allclose(relative_increments(truth)[0], [0.2, 0.0, 0.0])


def test_corners_of_a_corner_room_are_emitted_without_ids(tmp_path) -> None:
    """A 90-degree corner 3 m ahead and 1 m left, seen from a robot at rest: once confirmed
    (second scan on), one corner per scan, no ids, body frame."""
    angles = -np.pi / 2 + np.pi / 180 * np.arange(180)
    ranges = []
    for angle in angles:  # walls x = 3 (y <= 1) and y = 1 (x <= 3)
        hits = []
        if np.cos(angle) > 1e-9:
            hits.append(
                3.0 / np.cos(angle)
                if abs(3.0 * np.tan(angle)) <= 1.0 or np.tan(angle) < 0
                else np.inf
            )
        if np.sin(angle) > 1e-9:
            hits.append(1.0 / np.sin(angle) if 1.0 / np.tan(angle) <= 3.0 else np.inf)
        ranges.append(min(hits) if hits and min(hits) < 81.0 else 81.91)
    lines = [flaser(f"{100 + 0.2 * k:.6f}", (0.0, 0.0, 0.0), ranges) for k in range(3)]
    sequence = load(str(write_log(tmp_path / "f.clf", lines)), 0, {})
    scans = [m for m in sequence.measurements() if isinstance(m, LandmarkScan)]
    assert len(scans) == 2 and all(scan.ids is None for scan in scans)
    np.testing.assert_allclose(scans[0].points, [[3.0, 1.0]], atol=0.01)
    assert scans[0].covariances.shape == (1, 2, 2)
    assert sequence.pass_report.figures["corners"]["corners_confirmed"] == 2


def test_the_cli_reports_a_bad_log_in_one_error_line(tmp_path, capsys) -> None:
    from workbench.cli import main

    path = write_log(tmp_path / "bad.clf", ["FLASER 2 1.0 oops 0 0 0 0 0 0 5.0 h 0"])
    code = main(["run", "dead-reckoning", f"carmen:{path}", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("error:") and "bad.clf:3" in err[0]
