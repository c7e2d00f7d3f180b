"""Dataset ``scans:FOLDER``: KITTI .bin, PCD (ascii, binary), PLY (ascii, binary)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.measurements import LandmarkScan, Odometry, PointCloud
from datasets.scan_folder import read_scan
from datasets.synthetic_lidar.lidar import LidarModel, sweep
from datasets.synthetic_lidar.path import LoopPath
from datasets.synthetic_lidar.world import corridor_world
from workbench.registry import load_dataset


def _sweeps(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    world, path, model = corridor_world(), LoopPath(), LidarModel(columns=512)
    rng = np.random.default_rng(0)
    out = []
    for k in range(count):
        scan = sweep(world, path, model, 5.0 + 0.1 * k, rng)
        times = np.broadcast_to(scan.column_times, scan.points.shape[:2])
        finite = np.isfinite(scan.points[..., 0])
        out.append((scan.points[finite], times[finite]))
    return out


def _write_pcd(path, points, times, binary: bool) -> None:
    header = (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity time\nSIZE 4 4 4 4 4\nTYPE F F F F F\nCOUNT 1 1 1 1 1\n"
        f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\nDATA {'binary' if binary else 'ascii'}\n"
    )
    table = np.column_stack([points, np.ones(len(points)), times]).astype(np.float32)
    if binary:
        path.write_bytes(header.encode() + table.tobytes())
    else:
        path.write_text(
            header + "\n".join(" ".join(f"{v:.6f}" for v in row) for row in table) + "\n"
        )


def _write_ply(path, points, binary: bool) -> None:
    header = f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\nelement vertex {len(points)}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    table = points.astype(np.float32)
    if binary:
        path.write_bytes(header.encode() + table.tobytes())
    else:
        path.write_text(
            header + "\n".join(" ".join(f"{v:.6f}" for v in row) for row in table) + "\n"
        )


def test_formats_agree(tmp_path):
    ((points, times),) = _sweeps(1)
    stored = points.astype(np.float32).astype(np.float64)
    (tmp_path / "a.bin").write_bytes(
        np.column_stack([points, np.ones(len(points))]).astype("<f4").tobytes()
    )
    _write_pcd(tmp_path / "b.pcd", points, times, binary=True)
    _write_pcd(tmp_path / "c.pcd", points, times, binary=False)
    _write_ply(tmp_path / "d.ply", points, binary=True)
    _write_ply(tmp_path / "e.ply", points, binary=False)
    for name in ("a.bin", "b.pcd", "d.ply"):
        cloud = read_scan(tmp_path / name, 1.0)
        assert np.array_equal(cloud.points, stored), name
    for name in ("c.pcd", "e.ply"):
        assert np.allclose(read_scan(tmp_path / name, 1.0).points, stored, atol=2e-6), name
    assert read_scan(tmp_path / "a.bin", 1.0).point_times is None
    assert np.allclose(read_scan(tmp_path / "b.pcd", 1.0).point_times, times, atol=1e-7)


def test_scan_folder_sequence(tmp_path):
    for k, (points, times) in enumerate(_sweeps(4)):
        _write_pcd(tmp_path / f"{k:06d}.pcd", points, times, binary=True)
    (tmp_path / "times.txt").write_text("\n".join(f"{5.0 + 0.1 * k:.3f}" for k in range(4)) + "\n")
    sequence = load_dataset(f"scans:{tmp_path}", 0, {"kiss.max_num_threads": "1"})
    items = list(sequence.measurements())
    assert [m.t for m in items] == sorted(m.t for m in items)
    # the sequence starts at the first sweep's end (the first KISS-ICP pose): the first
    # cloud goes through the front end but is not emitted, and the first odometry
    # increment starts at the initial state
    start = sequence.initial_state.t
    assert 5.09 < start <= 5.1  # a 0.1 s sweep stamped 5.0
    assert items[0].t >= start
    assert sum(isinstance(m, PointCloud) for m in items) == 3
    odometry = [m for m in items if isinstance(m, Odometry)]
    assert len(odometry) == 3 and all(m.relative_pose.shape == (6,) for m in odometry)
    assert odometry[0].t - odometry[0].dt == pytest.approx(start, abs=1e-9)
    # truth: 0.15 m per frame along +x; KISS-ICP starts from standstill in a corridor and
    # lags over the first frames, so only the direction is checked here
    forward = np.array([m.relative_pose[3] for m in odometry])
    assert np.all((forward > 0.02) & (forward < 0.25))
    assert np.all(np.abs([m.relative_pose[4] for m in odometry]) < 0.05)
    assert any(isinstance(m, LandmarkScan) and m.count > 0 for m in items)


def test_without_deskewing_the_start_is_the_first_kept_scan(tmp_path):
    """An empty first file is skipped; without deskewing the sequence then starts at the
    second file's stamp (KISS-ICP's first pose), not at the first file's: an initial state
    before the first pose would put the whole run one frame of motion off."""
    _write_pcd(tmp_path / "000000.pcd", np.zeros((0, 3)), np.zeros(0), binary=True)
    for k, (points, times) in enumerate(_sweeps(3), start=1):
        _write_pcd(tmp_path / f"{k:06d}.pcd", points, times, binary=True)
    (tmp_path / "times.txt").write_text("\n".join(f"{5.0 + 0.1 * k:.3f}" for k in range(4)) + "\n")
    options = {"kiss.max_num_threads": "1", "kiss.deskew": "false"}
    sequence = load_dataset(f"scans:{tmp_path}", 0, options)
    items = list(sequence.measurements())
    assert sequence.initial_state.t == pytest.approx(5.1, abs=1e-12)
    odometry = [m for m in items if isinstance(m, Odometry)]
    assert len(odometry) == 2
    assert odometry[0].t - odometry[0].dt == pytest.approx(sequence.initial_state.t, abs=1e-9)
    assert [m.t for m in items if isinstance(m, PointCloud)] == pytest.approx([5.1, 5.2, 5.3])


def test_azimuth_point_times_for_clouds_without_them(tmp_path):
    """``point_times=azimuth``: a cloud without a time field gets KITTI raw's clockwise
    sweep, from behind (-T/2) through forward (the stamp) to behind again (+T/2), T the
    frame interval; the front end then deskews with them, so the sequence starts at the
    first sweep's end, half a frame after its stamp."""
    from datasets.lidar.sweep_times import azimuth_point_times

    bearings = np.radians([179.0, 90.0, 0.0, -90.0, -179.0])
    points = np.column_stack([np.cos(bearings), np.sin(bearings), np.zeros(5)])
    assert azimuth_point_times(points, 0.1) == pytest.approx(
        [-0.0497222, -0.025, 0.0, 0.025, 0.0497222], abs=1e-6
    )
    for k, (points, _) in enumerate(_sweeps(3)):
        (tmp_path / f"{k:06d}.bin").write_bytes(
            np.column_stack([points, np.ones(len(points))]).astype("<f4").tobytes()
        )
    (tmp_path / "times.txt").write_text("\n".join(f"{5.0 + 0.1 * k:.3f}" for k in range(3)) + "\n")
    options = {"kiss.max_num_threads": "1"}
    taken_as_compensated = load_dataset(f"scans:{tmp_path}", 0, options)
    items = list(taken_as_compensated.measurements())
    assert taken_as_compensated.initial_state.t == pytest.approx(5.0)
    assert all(m.point_times is None for m in items if isinstance(m, PointCloud))
    sequence = load_dataset(f"scans:{tmp_path}", 0, {**options, "point_times": "azimuth"})
    items = list(sequence.measurements())
    clouds = [m for m in items if isinstance(m, PointCloud)]
    assert len(clouds) == 2 and all(m.point_times is not None for m in clouds)
    stored = clouds[0].points
    assert np.allclose(clouds[0].point_times, azimuth_point_times(stored, 0.1), atol=1e-12)
    assert 5.049 < sequence.initial_state.t <= 5.05
    with_times = tmp_path / "with_times"
    with_times.mkdir()
    ((points, times),) = _sweeps(1)
    _write_pcd(with_times / "000000.pcd", points, times, binary=True)
    with pytest.raises(InputError, match="000000.pcd: has per-point times of its own"):
        list(load_dataset(f"scans:{with_times}", 0, {"point_times": "azimuth"}).measurements())
    odometry = [m for m in items if isinstance(m, Odometry)]
    assert [m.t for m in odometry] == pytest.approx(
        [
            t + float(np.max(azimuth_point_times(c.points, 0.1)))
            for t, c in ((5.1, clouds[0]), (5.2, clouds[1]))
        ]
    )


def test_bad_scans(tmp_path):
    (tmp_path / "000.bin").write_bytes(b"\0" * 20)
    with pytest.raises(
        InputError, match=r"000\.bin: 20 bytes is not a whole number of KITTI points"
    ):
        read_scan(tmp_path / "000.bin", 0.0)
    (tmp_path / "001.pcd").write_text(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary_compressed\n"
    )
    with pytest.raises(InputError, match="binary_compressed is not supported"):
        read_scan(tmp_path / "001.pcd", 0.0)
    (tmp_path / "002.pcd").write_text(
        "VERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2\n"
    )
    with pytest.raises(InputError, match=r"002\.pcd: no x/y/z field \(fields: a, b\)"):
        read_scan(tmp_path / "002.pcd", 0.0)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no .bin, .pcd or .ply scans"):
        load_dataset(f"scans:{empty}", 0, {})
    (tmp_path / "times.txt").write_text("0.0\n")
    with pytest.raises(InputError, match="1 times for 3 scans"):
        load_dataset(f"scans:{tmp_path}", 0, {})


def test_kiss_icp_max_range_comes_from_the_first_scan_and_is_recorded() -> None:
    from datasets.lidar.kiss_icp_odometry import range_from_scan

    rng = np.random.default_rng(0)
    directions = rng.normal(size=(20000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    outdoor = directions * rng.uniform(1.0, 78.0, (20000, 1))
    assert range_from_scan(outdoor)[0] == 100.0  # outdoors: KISS-ICP's own default
    assert range_from_scan(directions * 500.0)[0] == 100.0
    corridor = directions * rng.uniform(0.5, 18.0, (20000, 1))
    assert range_from_scan(corridor) == (
        20.0,
        "first scan (short-range: 99.9th range percentile 18.0 m)",
    )
    assert range_from_scan(directions * rng.uniform(0.5, 6.0, (20000, 1)))[0] == 10.0  # floor


@pytest.mark.study
def test_on_the_real_kitti_clip_the_default_front_end_is_kiss_icp_alone() -> None:
    """With no options, the front end's poses on the real clip are those of KISS-ICP run
    alone with its own defaults (``KISSConfig()``, voxel from its max range as its pipeline
    does), and the range it used is recorded with where it came from. The clip's scans are
    raw sweeps, which the defaults find (``point_times=auto``) and time by azimuth, as
    KISS-ICP's own KITTI-raw loader does: KISS-ICP alone is handed the same times (from the
    cut found, 181.7 deg, where its loader assumes 180)."""
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    from datasets.lidar.kiss_icp_odometry import normalized_point_times
    from datasets.lidar.sweep_times import CLOCKWISE, AzimuthSweep, point_times_for
    from datasets.scan_folder import ScanFolderOptions, read_scan, scans_sequence

    clip = Path(__file__).resolve().parents[2] / "shared" / "data" / "kitti-hdl64-clip"
    if not clip.is_dir():
        pytest.skip("../shared/data/kitti-hdl64-clip (real data) absent")
    sequence, source = scans_sequence(str(clip), ScanFolderOptions())
    for _ in sequence.measurements():
        pass
    resolved = sequence.pass_report.figures["kiss_icp"]
    assert {key: resolved[key] for key in ("max_range_m", "voxel_size_m", "max_range_source")} == {
        "max_range_m": 100.0,
        "voxel_size_m": 1.0,
        "max_range_source": "KISS-ICP default (first scan's 99.9th range percentile 78.2 m)",
    }
    assert resolved["kiss_icp_covariance_source"].startswith("re-observations")
    timing = sequence.metadata["sweep_timing"]
    assert timing["outcome"] == "raw" and timing["direction"] == "clockwise"
    assert abs(timing["start_deg"] - 180.0) < 10.0
    sweep = AzimuthSweep(timing["sweep_s"], CLOCKWISE, timing["start_deg"], timing["stamp"])
    config = KISSConfig()
    config.mapping.voxel_size = config.data.max_range / 100.0  # KISS-ICP's pipeline rule
    alone = KissICP(config)
    poses = []
    for path in sorted(clip.glob("*.pcd")):
        points = read_scan(path, 0.0).points
        times = normalized_point_times(point_times_for(points, None, sweep, str(path)))
        alone.register_frame(points, times)
        poses.append(np.array(alone.last_pose))
    ours = np.array([frame.pose for frame in source.front_end.frames])
    assert ours.shape == (30, 4, 4)
    assert np.max(np.abs(ours - np.array(poses))) < 1e-9
    # and the clip moves: 30 frames of a car, not a standstill that any setting matches
    assert np.linalg.norm(ours[-1, :3, 3]) > 10.0


def test_a_truth_file_that_jumps_is_excluded_from_the_scoring_and_said(tmp_path):
    """Any truth stream is judged (``datasets.truth_quality``): a TUM truth whose track jumps
    2 m away for three samples and back is excluded there, and the loader says so."""
    for k, (points, times) in enumerate(_sweeps(3)):
        _write_pcd(tmp_path / f"{k:06d}.pcd", points, times, binary=True)
    (tmp_path / "times.txt").write_text("\n".join(f"{5.0 + 0.1 * k:.3f}" for k in range(3)) + "\n")
    t = 4.0 + 0.01 * np.arange(1000)
    x = 1.5 * (t - t[0])
    x[140:143] += 2.0
    truth = tmp_path.parent / "truth.tum"
    truth.write_text("\n".join(f"{ti:.3f} {xi:.4f} 0 0 0 0 0 1" for ti, xi in zip(t, x)) + "\n")
    sequence = load_dataset(
        f"scans:{tmp_path}", 0, {"kiss.max_num_threads": "1", "ground_truth": str(truth)}
    )
    (interval,) = sequence.ground_truth.excluded
    assert interval.start_s == pytest.approx(t[140]) and interval.end_s == pytest.approx(t[142])
    assert any(
        "truth file" in line and "not trusted in 1 interval" in line
        for line in sequence.all_warnings()
    )
