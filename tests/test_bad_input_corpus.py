"""A corpus of corrupted inputs through the CLI: every case exits 2 with one ``error:`` line
naming the culprit (file, line, field, option or time), no traceback, and an earlier run
folder given as ``--out`` is left exactly as it was. Inputs are generated in ``tmp_path``."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main

TUM_OK = "\n".join(f"{0.1 * i:.1f} {0.5 * i} {0.1 * i**2 % 1} 0 0 0 0 1" for i in range(10))
KITTI_OK = "\n".join(f"1 0 0 {0.5 * i} 0 1 0 0 0 0 1 0" for i in range(10))

Builder = Callable[[Path], list[str]]
"""Writes the case's files into a folder and returns the command's arguments."""


def _tum_pair(est_text: str, ref_text: str = TUM_OK, command: str = "ate") -> Builder:
    def build(folder: Path) -> list[str]:
        (folder / "ref.tum").write_text(ref_text)
        est = folder / "est.tum"
        est.write_text(est_text) if isinstance(est_text, str) else est.write_bytes(est_text)
        return ["metrics", command, "--ref", str(folder / "ref.tum"), "--est", str(est)]

    return build


def _tum_lines(replace: dict[int, str]) -> str:
    lines = TUM_OK.splitlines()
    for index, text in replace.items():
        lines[index] = text
    return "\n".join(lines)


def _special_est(kind: str) -> Builder:
    def build(folder: Path) -> list[str]:
        (folder / "ref.tum").write_text(TUM_OK)
        est = folder / "est.tum"
        if kind == "folder":
            est.mkdir()
        elif kind == "fifo":
            os.mkfifo(est)
        return ["metrics", "ate", "--ref", str(folder / "ref.tum"), "--est", str(est)]

    return build


def _kitti_pair(est_text: str | bytes) -> Builder:
    def build(folder: Path) -> list[str]:
        (folder / "ref.kitti").write_text(KITTI_OK)
        est = folder / "est.kitti"
        est.write_bytes(est_text) if isinstance(est_text, bytes) else est.write_text(est_text)
        return [
            "metrics",
            "ate",
            "--ref",
            str(folder / "ref.kitti"),
            "--est",
            str(folder / "est.kitti"),
        ]

    return build


def _metrics_option(*extra: str, command: str = "ate") -> Builder:
    def build(folder: Path) -> list[str]:
        (folder / "ref.tum").write_text(TUM_OK)
        (folder / "est.tum").write_text(TUM_OK)
        files = ["--ref", str(folder / "ref.tum"), "--est", str(folder / "est.tum")]
        return ["metrics", command, *files, *extra]

    return build


# --------------------------------------------------------------------------- UTIAS
def _mrclam(folder: Path, change: Callable[[Path], None] | None = None) -> Path:
    root = folder / "mrclam"
    root.mkdir()
    (root / "Barcodes.dat").write_text("# subject barcode\n1 5\n6 72\n7 27\n")
    (root / "Landmark_Groundtruth.dat").write_text("# s x y sx sy\n6 2 0 0 0\n7 0 3 0 0\n")
    t = np.arange(400) * 0.02
    (root / "Robot1_Odometry.dat").write_text(
        "# t v w\n" + "\n".join(f"{x:.2f} 0.1 0.0" for x in t)
    )
    (root / "Robot1_Groundtruth.dat").write_text(
        "# t x y h\n" + "\n".join(f"{x:.2f} {0.1 * x:.4f} 0 0" for x in t)
    )
    (root / "Robot1_Measurement.dat").write_text(
        "# t b r phi\n" + "\n".join(f"{x:.2f} 72 2.0 0.1" for x in t[::10])
    )
    if change is not None:
        change(root)
    return root


def _utias(change: Callable[[Path], None] | None, robot: str = "robot1") -> Builder:
    def build(folder: Path) -> list[str]:
        root = _mrclam(folder, change)
        return [
            "run",
            "dead-reckoning",
            f"utias:{root}#{robot}",
            "--data",
            "odometry_noise=white",
            "--data",
            "odometry_speed_scale=1",
            "--data",
            "odometry_turn_scale=1",
            "--data",
            "odometry_speed_turn_coupling=0",
            "--data",
            "sighting_correlation=none",
        ]

    return build


def _rewrite(name: str, text: str | bytes) -> Callable[[Path], None]:
    def change(root: Path) -> None:
        path = root / name
        path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)

    return change


def _append(name: str, text: str) -> Callable[[Path], None]:
    def change(root: Path) -> None:
        path = root / name
        path.write_text(path.read_text() + "\n" + text)

    return change


def _remove(name: str) -> Callable[[Path], None]:
    return lambda root: (root / name).unlink()


def _repeat_truth_rows(root: Path) -> None:
    """Ten Groundtruth rows written twice (a copy-paste): time goes back in that file."""
    path = root / "Robot1_Groundtruth.dat"
    lines = path.read_text().splitlines()
    path.write_text("\n".join([*lines[:200], *lines[190:200], *lines[200:]]))


def _reverse_odometry(root: Path) -> None:
    path = root / "Robot1_Odometry.dat"
    lines = path.read_text().splitlines()
    path.write_text("\n".join([lines[0], *reversed(lines[1:])]))


# --------------------------------------------------------------------------- Victoria Park
VP_OK = [
    "ODOMETRY 0 1 0.5 0 0.01 0.0001 0 0 4e-06 0 4e-06",
    "LANDMARK 1 2 10.0 -3.0 0.4 0 0.4",
    "ODOMETRY 1 3 0.5 0 0.01 0.0001 0 0 4e-06 0 4e-06",
]


def _vp(lines: list[str] | bytes, *extra: str) -> Builder:
    def build(folder: Path) -> list[str]:
        path = folder / "vp.txt"
        path.write_bytes(lines) if isinstance(lines, bytes) else path.write_text("\n".join(lines))
        return ["run", "dead-reckoning", "victoria-park", "--data", f"path={path}", *extra]

    return build


# --------------------------------------------------------------------------- KITTI IMU/GPS
def _kitti_folder(change: Callable[[Path], None]) -> Builder:
    def build(folder: Path) -> list[str]:
        import gtsam

        data = Path(gtsam.__file__).parent / "Data"
        copy = folder / "kitti"
        copy.mkdir()
        for name in (
            "KittiEquivBiasedImu.txt",
            "KittiGps_converted.txt",
            "KittiEquivBiasedImu_metadata.txt",
        ):
            shutil.copy(data / name, copy / name)
        change(copy)
        return ["run", "dead-reckoning", "kitti-imu-gps", "--data", f"folder={copy}"]

    return build


def _edit_line(name: str, index: int, text: str) -> Callable[[Path], None]:
    def change(root: Path) -> None:
        path = root / name
        lines = path.read_text().splitlines()
        lines[index] = text
        path.write_text("\n".join(lines) + "\n")

    return change


# --------------------------------------------------------------------------- CLI options
def _cli(*argv: str) -> Builder:
    return lambda folder: list(argv)


def _config_file(text: str) -> Builder:
    def build(folder: Path) -> list[str]:
        path = folder / "config.yaml"
        path.write_text(text)
        return ["run", "ekf-slam", "sim:circle", "--data", "duration_s=1", "--config", str(path)]

    return build


def _out_is_a_file(folder: Path) -> list[str]:
    path = folder / "a_file"
    path.write_text("x")
    return ["run", "dead-reckoning", "sim:circle", "--data", "duration_s=1", "--out", str(path)]


# --------------------------------------------------------------------------- bags
def _bag_file(content: bytes | None, kind: str = "file") -> Builder:
    def build(folder: Path) -> list[str]:
        path = folder / "input.bag"
        if kind == "fifo":
            os.mkfifo(path)
        elif kind == "folder":
            path.mkdir()
        elif content is not None:
            path.write_bytes(content)
        return ["bag", str(path)]

    return build


def _synthetic_bag_then(change: Callable[[Path], list[str]]) -> Builder:
    def build(folder: Path) -> list[str]:
        from datasets.synthetic_lidar import write_lidar_bag

        bag = write_lidar_bag(folder / "corridor", 1, "ros1", {"duration_s": "0.5"})
        return ["bag", str(bag), *change(bag)]

    return build


def _truncate(bag: Path) -> list[str]:
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 3])
    return []


def _ros2_without_metadata(folder: Path) -> list[str]:
    bag = folder / "ros2bag"
    bag.mkdir()
    (bag / "ros2bag_0.db3").write_bytes(b"SQLite format 3\x00" + bytes(100))
    return ["bag", str(bag)]


def _ros2_with_broken_metadata(folder: Path) -> list[str]:
    bag = folder / "ros2bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [not, a, mapping")
    return ["bag", str(bag)]


def _mcap_garbage(folder: Path) -> list[str]:
    path = folder / "x.mcap"
    path.write_bytes(b"\x89MCAP0\r\n" + bytes(64))
    return ["bag", str(path)]


CASES: list[tuple[str, Builder, str]] = [
    # ---- TUM files (metrics ate / rpe)
    (
        "tum missing",
        lambda f: ["metrics", "ate", "--ref", str(f / "a"), "--est", str(f / "b")],
        "no such file",
    ),
    ("tum is a folder", _special_est("folder"), "is a folder"),
    ("tum is a fifo", _special_est("fifo"), "is a FIFO"),
    ("tum random bytes", _tum_pair(bytes(range(128, 256))), "not a UTF-8"),
    ("tum nul bytes", _tum_pair("0 0 0 0 0 0 0 1\x00\n"), "NUL"),
    (
        "tum seven fields",
        _tum_pair(_tum_lines({2: "0.2 1 2 3 0 0 1"})),
        "est.tum:3: expected 8 numbers",
    ),
    (
        "tum nine fields",
        _tum_pair(_tum_lines({2: "0.2 1 2 3 0 0 0 1 9"})),
        "est.tum:3: expected 8 numbers",
    ),
    (
        "tum not a number",
        _tum_pair(_tum_lines({4: "0.4 x 0 0 0 0 0 1"})),
        "est.tum:5: not a number",
    ),
    ("tum nan", _tum_pair(_tum_lines({4: "0.4 nan 0 0 0 0 0 1"})), "est.tum:5: non-finite"),
    ("tum inf", _tum_pair(_tum_lines({4: "0.4 inf 0 0 0 0 0 1"})), "est.tum:5: non-finite"),
    (
        "tum 1e308",
        _tum_pair(_tum_lines({4: "0.4 1e308 0 0 0 0 0 1"})),
        "est.tum:5: position beyond",
    ),
    (
        "tum out of order",
        _tum_pair(_tum_lines({3: "0.1 0 0 0 0 0 0 1"})),
        "est.tum:4: time 0.1 is not after",
    ),
    (
        "tum repeated stamp",
        _tum_pair(_tum_lines({3: "0.2 5 5 5 0 0 0 1"})),
        "est.tum:4: time 0.2 is not after",
    ),
    (
        "tum all stamps equal",
        _tum_pair("\n".join(f"1.0 {i} 0 0 0 0 0 1" for i in range(5))),
        "est.tum:2: time 1.0 is not after",
    ),
    (
        "tum zero quaternion",
        _tum_pair(_tum_lines({5: "0.5 0 0 0 0 0 0 0"})),
        "est.tum:6: zero quaternion",
    ),
    ("tum empty", _tum_pair(""), "est.tum: no poses"),
    ("tum only comments", _tum_pair("# t x y z qx qy qz qw\n# nothing\n"), "est.tum: no poses"),
    (
        "tum bad reference",
        _tum_pair(TUM_OK, _tum_lines({1: "0.1 a 0 0 0 0 0 1"})),
        "ref.tum:2: not a number",
    ),
    (
        "tum no common stamps",
        _tum_pair("\n".join(f"{100 + i} {i} 0 0 0 0 0 1" for i in range(5))),
        "no matching timestamps",
    ),
    (
        "tum rpe out of order",
        _tum_pair(_tum_lines({3: "0.1 0 0 0 0 0 0 1"}), command="rpe"),
        "est.tum:4",
    ),
    # ---- KITTI poses
    (
        "kitti eleven numbers",
        _kitti_pair("1 0 0 0 0 1 0 0 0 0 1"),
        "est.kitti:1: expected 12 numbers",
    ),
    (
        "kitti not a rotation",
        _kitti_pair("2 0 0 0 0 1 0 0 0 0 1 0"),
        "est.kitti:1: the 3x3 block is not a rotation",
    ),
    ("kitti nan", _kitti_pair("1 0 0 nan 0 1 0 0 0 0 1 0"), "est.kitti:1: non-finite"),
    ("kitti 1e308", _kitti_pair("1 0 0 1e308 0 1 0 0 0 0 1 0"), "est.kitti:1: position beyond"),
    ("kitti empty", _kitti_pair(""), "est.kitti: no poses"),
    ("kitti random bytes", _kitti_pair(b"\xff\xfe\x00"), "est.kitti: not a UTF-8"),
    # ---- metrics options
    ("metrics bad align", _metrics_option("--align", "affine"), "--align must be one of"),
    (
        "metrics negative max diff",
        _metrics_option("--max-diff", "-1"),
        "--max-diff must be a positive",
    ),
    ("metrics nan max diff", _metrics_option("--max-diff", "nan"), "--max-diff must be a positive"),
    (
        "metrics zero delta",
        _metrics_option("--delta", "0", command="rpe"),
        "--delta must be a positive",
    ),
    (
        "metrics bad unit",
        _metrics_option("--unit", "parsec", command="rpe"),
        "--unit must be frames or m",
    ),
    (
        "metrics fractional frames",
        _metrics_option("--delta", "1.5", command="rpe"),
        "delta in frames must be an integer",
    ),
    # ---- UTIAS MRCLAM folders
    (
        "utias folder missing",
        lambda f: ["run", "dead-reckoning", f"utias:{f}/absent#robot1"],
        "does not exist",
    ),
    ("utias bad robot", _utias(None, robot="robotX"), "robot must be written robotN"),
    ("utias no barcodes file", _utias(_remove("Barcodes.dat")), "Barcodes.dat: no such file"),
    (
        "utias no odometry file",
        _utias(_remove("Robot1_Odometry.dat")),
        "Robot1_Odometry.dat: no such file",
    ),
    (
        "utias odometry two columns",
        _utias(_append("Robot1_Odometry.dat", "8.00 0.1")),
        "Robot1_Odometry.dat:402: expected 3 columns",
    ),
    (
        "utias odometry not a number",
        _utias(_append("Robot1_Odometry.dat", "8.00 0.1 x")),
        "Robot1_Odometry.dat:402: not a number",
    ),
    (
        "utias truth nan",
        _utias(_append("Robot1_Groundtruth.dat", "8.00 nan 0 0")),
        "Robot1_Groundtruth.dat:402: non-finite",
    ),
    (
        "utias measurement binary",
        _utias(_rewrite("Robot1_Measurement.dat", b"\x80\x81\x82")),
        "Robot1_Measurement.dat: not a UTF-8",
    ),
    (
        "utias odometry empty",
        _utias(_rewrite("Robot1_Odometry.dat", "# nothing\n")),
        "Robot1_Odometry.dat: no data rows",
    ),
    ("utias odometry backwards", _utias(_reverse_odometry), "do not increase in time"),
    # the file that goes back is the one named (it read Robot1_Odometry.dat:50002)
    ("utias truth rows repeated", _utias(_repeat_truth_rows), "Robot1_Groundtruth.dat:201"),
    (
        # a sighting outside the odometry's span is an edge (trimmed, warned); one that goes
        # back in time inside it is a broken file
        "utias sighting back in time",
        _utias(_append("Robot1_Measurement.dat", "0.04 72 2.0 0.1")),
        "1 of 41 sightings go back in time",
    ),
    (
        "utias barcode twice",
        _utias(_append("Barcodes.dat", "8 72")),
        "Barcodes.dat:6: barcode 72 listed twice",
    ),
    (
        "utias survey file is a folder",
        _utias(
            lambda r: (
                (r / "Landmark_Groundtruth.dat").unlink(),
                (r / "Landmark_Groundtruth.dat").mkdir(),
            )
        ),
        "Landmark_Groundtruth.dat: is a folder",
    ),
    (
        "utias bad data option",
        _utias(None) if False else lambda f: [*_utias(None)(f), "--data", "grid_step_s=-1"],
        "grid_step_s",
    ),
    ("utias unknown data option", lambda f: [*_utias(None)(f), "--data", "robots=3"], "known keys"),
    # ---- Victoria Park files
    (
        "vp missing",
        lambda f: ["run", "dead-reckoning", "victoria-park", "--data", f"path={f}/none.txt"],
        "none.txt: no such file",
    ),
    ("vp unknown tag", _vp([*VP_OK, "POSE 3 0 0 0"]), "vp.txt:4: unknown tag 'POSE'"),
    (
        "vp short odometry",
        _vp([*VP_OK, "ODOMETRY 3 4 0.5 0 0.01"]),
        "vp.txt:4: ODOMETRY needs 11 fields",
    ),
    (
        "vp broken chain",
        _vp([*VP_OK, "ODOMETRY 7 8 0.5 0 0.01 0.0001 0 0 4e-06 0 4e-06"]),
        "vp.txt:4: odometry starts from pose 7",
    ),
    (
        "vp covariance not pd",
        _vp([*VP_OK, "ODOMETRY 3 4 0.5 0 0.01 0.0001 0 0 0 0 4e-06"]),
        "vp.txt:4: odometry covariance is not positive definite",
    ),
    (
        "vp landmark covariance not pd",
        _vp([*VP_OK, "LANDMARK 3 5 1 1 -0.4 0 0.4"]),
        "vp.txt:4: landmark covariance is not positive definite",
    ),
    (
        "vp non-finite",
        _vp([*VP_OK, "ODOMETRY 3 4 nan 0 0.01 0.0001 0 0 4e-06 0 4e-06"]),
        "vp.txt:4: non-finite",
    ),
    (
        "vp not a number",
        _vp([*VP_OK, "ODOMETRY 3 4 x 0 0.01 0.0001 0 0 4e-06 0 4e-06"]),
        "vp.txt:4: malformed number",
    ),
    ("vp no odometry", _vp(["# only a comment"]), "vp.txt: no ODOMETRY lines"),
    ("vp binary", _vp(b"\xff\xd8\xff\xe0"), "vp.txt: not a UTF-8"),
    ("vp negative step", _vp(VP_OK, "--data", "step_s=-1"), "step_s"),
    # ---- KITTI IMU/GPS folders
    (
        "kitti imu missing",
        _kitti_folder(_remove("KittiEquivBiasedImu.txt")),
        "KittiEquivBiasedImu.txt: no such file",
    ),
    (
        "kitti gps missing",
        _kitti_folder(_remove("KittiGps_converted.txt")),
        "KittiGps_converted.txt: no such file",
    ),
    (
        "kitti imu bad header",
        _kitti_folder(_edit_line("KittiEquivBiasedImu.txt", 0, "t a b")),
        "KittiEquivBiasedImu.txt:1: expected the header",
    ),
    (
        "kitti imu nan",
        _kitti_folder(_edit_line("KittiEquivBiasedImu.txt", 5, "nan " * 8)),
        "KittiEquivBiasedImu.txt:6: non-finite",
    ),
    (
        "kitti imu short line",
        _kitti_folder(_edit_line("KittiEquivBiasedImu.txt", 5, "1 2 3")),
        "KittiEquivBiasedImu.txt:6: expected 8 values",
    ),
    (
        "kitti gps not a number",
        _kitti_folder(_edit_line("KittiGps_converted.txt", 3, "x,y,z,w")),
        "KittiGps_converted.txt:4: a value is not a number",
    ),
    (
        "kitti imu time backwards",
        _kitti_folder(_edit_line("KittiEquivBiasedImu.txt", 10, "0 " * 8)),
        "KittiEquivBiasedImu.txt:11: time does not increase",
    ),
    (
        "kitti metadata binary",
        _kitti_folder(_rewrite("KittiEquivBiasedImu_metadata.txt", b"\xfe\xff\x00\x01")),
        "KittiEquivBiasedImu_metadata.txt: not a UTF-8",
    ),
    # ---- bags (ROS 1, ROS 2 sqlite3, mcap)
    ("bag missing", lambda f: ["bag", str(f / "none.bag")], "none.bag: no such bag"),
    ("bag is a fifo", _bag_file(None, "fifo"), "input.bag: is a FIFO"),
    ("bag random bytes", _bag_file(bytes(range(256)) * 8), "input.bag: cannot open bag"),
    ("bag empty file", _bag_file(b""), "input.bag: cannot open bag"),
    ("bag folder without metadata", _bag_file(None, "folder"), "needs its metadata.yaml"),
    (
        "ros2 sqlite3 without metadata",
        _ros2_without_metadata,
        "ros2bag: a ROS 2 bag folder needs its metadata.yaml",
    ),
    ("ros2 broken metadata", _ros2_with_broken_metadata, "ros2bag: cannot open bag"),
    ("mcap garbage", _mcap_garbage, "x.mcap: cannot open bag"),
    ("bag truncated", _synthetic_bag_then(_truncate), "corridor"),
    ("bag missing lidar topic", _synthetic_bag_then(lambda b: ["--lidar-topic", "/nope"]), "/nope"),
    (
        "bag missing truth topic",
        _synthetic_bag_then(lambda b: ["--truth-topic", "/truth"]),
        "/truth",
    ),
    ("bag unknown estimator", _synthetic_bag_then(lambda b: ["--estimator", "nope"]), "nope"),
    (
        "bag bad kiss option",
        _synthetic_bag_then(lambda b: ["--data", "kiss.voxel_size_m=-1"]),
        "voxel_size_m",
    ),
    ("bag negative threads", _synthetic_bag_then(lambda b: ["--threads", "-1"]), "--threads"),
    # ---- CLI options
    ("run unknown estimator", _cli("run", "kalman-magic", "sim:circle"), "kalman-magic"),
    ("run unknown dataset", _cli("run", "ekf-slam", "sim:nowhere"), "nowhere"),
    ("run unknown prefix", _cli("run", "ekf-slam", "nowhere:x"), "nowhere"),
    ("run bad set key", _cli("run", "ekf-slam", "sim:circle", "--set", "gate=0.5"), "gate"),
    (
        "run bad set value",
        _cli("run", "ekf-slam", "sim:circle", "--set", "gate_probability=2"),
        "gate_probability",
    ),
    (
        "run set without equals",
        _cli("run", "ekf-slam", "sim:circle", "--set", "gate_probability"),
        "--set expects key=value",
    ),
    ("run bad data key", _cli("run", "ekf-slam", "sim:circle", "--data", "speed=3"), "speed"),
    (
        "run bad data value",
        _cli("run", "ekf-slam", "sim:circle", "--data", "duration_s=-5"),
        "duration_s",
    ),
    ("run negative seed", _cli("run", "ekf-slam", "sim:circle", "--seed", "-1"), "--seed"),
    (
        "run empty out",
        _cli("run", "dead-reckoning", "sim:circle", "--data", "duration_s=1", "--out", ""),
        "--out",
    ),
    ("run out is a file", _out_is_a_file, "exists and is not a folder"),
    (
        "run missing config",
        _cli("run", "ekf-slam", "sim:circle", "--config", "/nonexistent.yaml"),
        "nonexistent.yaml",
    ),
    ("run config not yaml", _config_file("gate_probability: [0.5"), "not valid YAML"),
    ("run config not a mapping", _config_file("- 1\n- 2\n"), "expected a mapping"),
    ("run config bad key", _config_file("gate: 0.5\n"), "gate"),
    (
        "run bad plot format",
        _cli("run", "dead-reckoning", "sim:circle", "--plot-format", "gif"),
        "gif",
    ),
    (
        "run incompatible",
        _cli("run", "aghili", "sim:guerreiro-loop", "--data", "duration_s=1"),
        "aghili",
    ),
    (
        "simulate unknown scenario",
        _cli("simulate", "moon-base", "--out", "/tmp/never"),
        "moon-base",
    ),
    ("bench unknown suite", _cli("bench", "fastest"), "fastest"),
    ("bench unknown dataset", _cli("bench", "tiny", "--dataset", "sim:moon"), "sim:moon"),
    ("bench zero runs", _cli("bench", "tiny", "--runs", "0"), "--runs"),
    (
        "observability bad value",
        _cli("observability", "sim:aghili-rover", "--set", "anchors=abc"),
        "anchors=abc",
    ),
    (
        "observability unknown key",
        _cli("observability", "sim:aghili-rover", "--set", "speed=1"),
        "speed",
    ),
    (
        "calibrate-noise without odometry",
        _cli("calibrate-noise", "sim:circle", "--data", "duration_s=1"),
        "circle",
    ),
    ("config unknown estimator", _cli("config", "kalman-magic"), "kalman-magic"),
    ("unknown command", _cli("fly"), "fly"),
]


@pytest.fixture(scope="module")
def earlier_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, bytes]]:
    """A finished run folder every case is pointed at with --out (where it takes one)."""
    folder = tmp_path_factory.mktemp("earlier") / "run"
    argv = ["run", "dead-reckoning", "sim:circle", "--data", "duration_s=1", "--no-plots"]
    assert main([*argv, "--out", str(folder)]) == 0
    return folder, {p.name: p.read_bytes() for p in folder.iterdir()}


def _takes_out(argv: list[str]) -> bool:
    return bool(argv) and argv[0] in ("run", "bag") and "--out" not in argv


@pytest.mark.parametrize(("name", "build", "culprit"), CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_clear_error_and_loses_nothing(
    name: str, build: Builder, culprit: str, tmp_path: Path, earlier_run, capsys
) -> None:
    folder, before = earlier_run
    argv = build(tmp_path)
    fresh_out = tmp_path / "bag-out"  # bag writes a collection, never into a run folder
    if _takes_out(argv):
        argv = [*argv, "--out", str(folder if argv[0] == "run" else fresh_out)]
    capsys.readouterr()
    status = main(argv)
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert status == 2, (status, captured.err)
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1 and len(lines) == 1, lines  # one line, nothing else
    assert culprit in errors[0], errors[0]
    assert "Traceback" not in captured.err and "internal error" not in captured.err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".run.")]
    assert not fresh_out.exists()  # refused before anything was written


def test_the_corpus_covers_every_source() -> None:
    groups = {name.split()[0] for name, _, _ in CASES}
    assert len(CASES) >= 80
    assert {"tum", "kitti", "utias", "vp", "bag", "ros2", "mcap", "run", "metrics"} <= groups


# ------------------------------------------------------------- destinations that refuse
# sysfs refuses every new entry, even to root (these tests run as root, for whom permission
# bits do not apply): the real kernel error, not a mock
UNWRITABLE = Path("/sys/workbench-cannot-write-here")
needs_sysfs = pytest.mark.skipif(
    not Path("/sys/kernel").is_dir(), reason="needs Linux sysfs for an unwritable folder"
)


@needs_sysfs
@pytest.mark.parametrize(
    "argv",
    [
        ["run", "dead-reckoning", "sim:circle", "--data", "duration_s=1", "--no-plots"],
        ["simulate", "circle", "--data", "duration_s=1"],
        ["bench", "tiny", "--runs", "1", "--no-plots"],
        ["simulate", "lidar-corridor", "--data", "duration_s=0.2"],
    ],
    ids=["run", "simulate", "bench", "simulate-bag"],
)
def test_an_unwritable_destination_is_one_clear_error(argv: list[str], capsys) -> None:
    status = main([*argv, "--out", str(UNWRITABLE / "out")])
    captured = capsys.readouterr()
    errors = [line for line in captured.err.splitlines() if line.startswith("error: ")]
    assert status == 2, captured.err
    assert len(errors) == 1 and str(UNWRITABLE) in errors[0], captured.err
    assert "Traceback" not in captured.err and "internal error" not in captured.err


def test_a_full_disk_mid_write_keeps_the_earlier_run(
    earlier_run, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """The disk fills while the new run folder is written: one error line naming the file,
    exit 2, the earlier run untouched, nothing left beside it."""
    import errno

    import workbench.run_folder

    folder, before = earlier_run

    def no_space(path, arrays) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(workbench.run_folder, "save_npz_atomic", no_space)
    argv = ["run", "dead-reckoning", "sim:circle", "--data", "duration_s=1", "--no-plots"]
    status = main([*argv, "--out", str(folder)])
    captured = capsys.readouterr()
    assert status == 2, captured.err
    assert captured.err.strip().startswith("error: ") and captured.err.count("\n") == 1
    assert "estimate.npz: No space left on device" in captured.err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".run.")]
