"""More corrupted inputs through the CLI, checked for meaning and not only form: trajectory
files (KITTI never paired by seconds, suffix against content), scan folders (a frame twice,
broken PCD/PLY bodies and headers, bad frame times) and bags (coordinate types, cloud
layouts, implausible IMU samples, points, stamps and truth poses, messages that do not
decode, flipped words). Every case exits 2 with one ``error:`` line naming the culprit, no
traceback, and an earlier run folder given as ``--out`` left as it was
(``tests/test_bad_input_corpus.py`` runs the earlier corpus the same way). Inputs are
generated in ``tmp_path``."""

from __future__ import annotations

import dataclasses
import re
import sqlite3
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from datasets.bags.pointcloud2 import encode_pointcloud2
from tests import test_bad_input_corpus as corpus
from tests.test_bags_bad_input import TYPESTORE, T, _box_points, _cloud, _header, _imu, write_ros2
from workbench.cli import main

Builder = corpus.Builder
earlier_run = corpus.earlier_run  # the same earlier run folder fixture, for this module

# ------------------------------------------------------------------------ trajectory files
POSES = 12


def _tum_rows(count: int = POSES, start_s: float = 0.0) -> str:
    return "".join(
        f"{start_s + 0.1 * i:.1f} {0.5 * i} {0.1 * i**2 % 1} 0 0 0 0 1\n" for i in range(count)
    )


def _kitti_rows(count: int = POSES, skip: int | None = None) -> str:
    return "".join(
        f"1 0 0 {0.5 * i} 0 1 0 {0.1 * i**2 % 1} 0 0 1 0\n" for i in range(count) if i != skip
    )


def _files(
    ref: tuple[str, str], est: tuple[str, str], *extra: str, command: str = "ate"
) -> Builder:
    """``metrics COMMAND --ref NAME --est NAME`` of two files (name, text)."""

    def build(folder: Path) -> list[str]:
        paths = []
        for name, text in (ref, est):
            (folder / name).write_text(text)
            paths.append(str(folder / name))
        return ["metrics", command, "--ref", paths[0], "--est", paths[1], *extra]

    return build


TRAJECTORY_CASES: list[tuple[str, Builder, str]] = [
    (
        "kitti ref with a shorter tum est",
        _files(("ref.kitti", _kitti_rows()), ("est.tum", _tum_rows(POSES - 1))),
        "ref.kitti holds 12 poses and --est",
    ),
    (
        "two kitti files one pose deleted",
        _files(("ref.kitti", _kitti_rows()), ("est.kitti", _kitti_rows(skip=5))),
        "est.kitti holds 11: KITTI poses carry no time",
    ),
    (
        "kitti rows in a txt file against a longer tum",
        _files(("ref.tum", _tum_rows(POSES + 3)), ("est.txt", _kitti_rows())),
        "ref.tum holds 15 poses",
    ),
    (
        "rpe on kitti files of different lengths",
        _files(("ref.kitti", _kitti_rows()), ("est.kitti", _kitti_rows(8)), command="rpe"),
        "est.kitti holds 8",
    ),
    (
        "tum rows in a .kitti file",
        _files(("ref.tum", _tum_rows()), ("est.kitti", "# poses\n" + _tum_rows())),
        "est.kitti:2: named .kitti but its rows hold 8 numbers",
    ),
    (
        "kitti rows in a .tum file",
        _files(("ref.tum", _kitti_rows()), ("est.tum", _tum_rows())),
        "ref.tum:1: named .tum but its rows hold 12 numbers",
    ),
    (
        "kitti pose with determinant -1",
        _files(
            ("ref.kitti", _kitti_rows()),
            ("est.kitti", _kitti_rows(5) + "1 0 0 0 0 1 0 0 0 0 -1 0\n"),
        ),
        "est.kitti:6: the 3x3 block has determinant -1",
    ),
    (
        "kitti rows in a txt file with a short row",
        _files(
            ("ref.kitti", _kitti_rows()), ("est.txt", _kitti_rows(3) + "1 0 0 0 0 1 0 0 0 0 1\n")
        ),
        "est.txt:4: expected 12 numbers",
    ),
    (
        "tum files that only touch in time",
        _files(("ref.tum", _tum_rows(10)), ("est.tum", _tum_rows(10, start_s=0.9))),
        "do not overlap in time",
    ),
    (
        "rpe delta beyond the poses",
        _files(("ref.tum", _tum_rows()), ("est.tum", _tum_rows()), "--delta", "50", command="rpe"),
        "--delta 50 frames gives no pose pair among 12 poses; try a smaller --delta",
    ),
    (
        "rpe delta in metres beyond the path",
        _files(
            ("ref.tum", _tum_rows()),
            ("est.tum", _tum_rows()),
            *("--delta", "1000", "--unit", "m"),
            command="rpe",
        ),
        "--delta 1000 m gives no pose pair",
    ),
]

# ------------------------------------------------------------------------ scan folders
PCD_HEADER = (
    "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
    "WIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA {mode}\n"
)


def _points(count: int = 400) -> np.ndarray:
    return np.column_stack([_box_points(np.random.default_rng(7))[:count], np.ones(count)])


def _ascii(points: np.ndarray) -> str:
    return "".join(" ".join(f"{v:.4f}" for v in row) + "\n" for row in points)


def _pcd(mode: str = "binary", header: str = PCD_HEADER, body: bytes | None = None) -> bytes:
    points = _points()
    if body is None:
        body = points.astype("<f4").tobytes() if mode == "binary" else _ascii(points).encode()
    return header.format(n=len(points), mode=mode).encode() + body


def _ply(fmt: str = "ascii", vertex: str = "element vertex {n}", body: str | None = None) -> bytes:
    points = _points()[:, :3]
    header = (
        f"ply\nformat {fmt} 1.0\n{vertex.format(n=len(points))}\n"
        "property float x\nproperty float y\nproperty float z\nend_header\n"
    )
    return header.encode() + (_ascii(points) if body is None else body).encode()


def _bin() -> bytes:
    return _points().astype("<f4").tobytes()


def _scans(files: dict[str, bytes], *data: str) -> Builder:
    """``run dead-reckoning scans:FOLDER`` of a folder holding ``files`` (name: bytes)."""

    def build(folder: Path) -> list[str]:
        scans = folder / "scans"
        scans.mkdir()
        for name, content in files.items():
            (scans / name).write_bytes(content)
        options = [item for option in data for item in ("--data", option)]
        return ["run", "dead-reckoning", f"scans:{scans}", *options]

    return build


def _edit(text: bytes, old: str, new: str) -> bytes:
    assert old.encode() in text
    return text.replace(old.encode(), new.encode(), 1)


GOOD = {"000001.bin": _bin(), "000002.bin": _bin()}
ASCII_BODY = _ascii(_points())
PLY_BODY = _ascii(_points()[:, :3])
LINE_OF_ROW_3 = 9 + 3  # nine header lines, then the rows

SCAN_CASES: list[tuple[str, Builder, str]] = [
    (
        "scans frame twice as bin and pcd",
        _scans({**GOOD, "000000.bin": _bin(), "000000.pcd": _pcd()}),
        "frame 000000 is there twice, as 000000.bin and 000000.pcd",
    ),
    (
        "scans frame twice as pcd and PCD",
        _scans({**GOOD, "000003.PCD": _pcd(), "000003.pcd": _pcd()}),
        "frame 000003 is there twice, as 000003.PCD and 000003.pcd",
    ),
    (
        "pcd four fields three sizes",
        _scans({"000000.pcd": _edit(_pcd(), "SIZE 4 4 4 4", "SIZE 4 4 4"), **GOOD}),
        "000000.pcd: PCD header declares 4 FIELDS (x y z intensity) but 3 SIZE values",
    ),
    (
        "pcd four fields three types",
        _scans({"000000.pcd": _edit(_pcd(), "TYPE F F F F", "TYPE F F F"), **GOOD}),
        "000000.pcd: PCD header declares 4 FIELDS (x y z intensity) but 3 TYPE values",
    ),
    (
        "pcd upper-case suffix is read as pcd",
        _scans({"000000.PCD": _edit(_pcd(), "COUNT 1 1 1 1", "COUNT 1 1"), **GOOD}),
        "000000.PCD: PCD header declares 4 FIELDS (x y z intensity) but 2 COUNT values",
    ),
    (
        "pcd ascii with a word",
        _scans({"000000.pcd": _edit(_pcd("ascii"), ASCII_BODY.splitlines()[2], "1.0 2.0 oops 1")}),
        f"000000.pcd:{LINE_OF_ROW_3}: 'oops' is not a number",
    ),
    (
        "pcd ascii with a short row",
        _scans({"000000.pcd": _edit(_pcd("ascii"), ASCII_BODY.splitlines()[2], "1.0 2.0 3.0")}),
        f"000000.pcd:{LINE_OF_ROW_3}: 3 values, its header declares 4 (FIELDS x y z intensity)",
    ),
    (
        "pcd ascii header with a binary body",
        _scans({"000000.pcd": _pcd("ascii", body=_bin())}),
        "000000.pcd: declared ascii, but its body holds binary bytes",
    ),
    (
        "pcd binary header with an ascii body",
        _scans({"000000.pcd": _pcd("binary", body=ASCII_BODY.encode())}),
        "000000.pcd: declared DATA binary, but its body is text",
    ),
    (
        "pcd ascii fewer rows than points",
        _scans(
            {"000000.pcd": _pcd("ascii", body="".join(ASCII_BODY.splitlines(True)[:300]).encode())}
        ),
        "000000.pcd: 300 point rows, its header declares 400",
    ),
    (
        "pcd binary truncated",
        _scans({"000000.pcd": _pcd()[:-100]}),
        "000000.pcd: PCD binary data is 6300 bytes, header declares 6400",
    ),
    (
        "pcd type that pcd does not have",
        _scans({"000000.pcd": _edit(_pcd(), "SIZE 4 4 4 4", "SIZE 4 4 2 4")}),
        "000000.pcd: PCD field 'z' has TYPE F SIZE 2",
    ),
    (
        "pcd data line without a mode",
        _scans({"000000.pcd": _edit(_pcd(), "DATA binary", "DATA")}),
        "000000.pcd: PCD DATA (nothing) is not supported",
    ),
    (
        "ply ascii with a word",
        _scans({"000000.ply": _ply(body=PLY_BODY.replace(PLY_BODY.split()[1], "nope", 1))}),
        "000000.ply:8: 'nope' is not a number",
    ),
    (
        "ply vertex count not a number",
        _scans({"000000.ply": _ply(vertex="element vertex many")}),
        "000000.ply:3: malformed PLY header line 'element vertex many'",
    ),
    (
        "ply binary truncated",
        _scans({"000000.ply": _ply("binary_little_endian", body="")}),
        "000000.ply: PLY data is 0 bytes, header declares 4800",
    ),
    (
        "bin not whole points",
        _scans({"000000.bin": _bin()[:-6], **GOOD}),
        "000000.bin: 6394 bytes is not a whole number of KITTI points",
    ),
    (
        "scans times nan",
        _scans({**GOOD, "times.txt": b"0.0\nnan\n0.2\n"}),
        "times.txt:2: time 'nan' is not finite",
    ),
    (
        "scans times inf",
        _scans({**GOOD, "times.txt": b"0.0\n0.1\ninf\n"}),
        "times.txt:3: time 'inf' is not finite",
    ),
    (
        "scans times not utf-8",
        _scans({**GOOD, "times.txt": b"0.0\n\xff\xfe0.1\n"}),
        "times.txt: not a UTF-8 text timestamps file",
    ),
    (
        "scans times with a word",
        _scans({**GOOD, "times.txt": b"0.0\nsoon\n"}),
        "times.txt:2: not a time 'soon'",
    ),
]

# ------------------------------------------------------------------------ bags
CLOUDS, IMU_SAMPLES = 5, 50
Change = Callable[[int, object], object]
"""Takes the index of a message on its topic and the message, returns the one to write."""


def _at(indices: tuple[int, ...], change: Change) -> Change:
    return lambda k, message: change(k, message) if k in indices else message


def _bag(
    clouds: Change | None = None,
    imu: Change | None = None,
    truth: Change | None = None,
    gps: Change | None = None,
    after: Callable[[Path], None] | None = None,
) -> Builder:
    """``bag`` of a small ROS 2 bag: box-room clouds at 10 Hz (logged a sweep later, as
    drivers do), IMU samples at 100 Hz, and when asked a truth topic (named with
    ``--truth-topic``) and GPS fixes, each message passed through its ``change``; ``after``
    may then damage the bag's storage."""

    def build(folder: Path) -> list[str]:
        rng = np.random.default_rng(11)
        messages = []
        for k in range(CLOUDS):
            t = 1.0 + 0.1 * k
            cloud = _cloud(t, _box_points(rng))
            messages.append(
                ("/cloud", "sensor_msgs/msg/PointCloud2", t + 0.1, (clouds or _keep)(k, cloud))
            )
        for k in range(IMU_SAMPLES):
            t = 1.0 + 0.01 * k
            messages.append(("/imu", "sensor_msgs/msg/Imu", t, (imu or _keep)(k, _imu(t))))
        if truth is not None:
            for k in range(40):
                t = 1.0 + 0.02 * k
                messages.append(("/truth", "geometry_msgs/msg/PoseStamped", t, truth(k, _pose(t))))
        if gps is not None:
            for k in range(CLOUDS):
                t = 1.0 + 0.1 * k
                messages.append(("/fix", "sensor_msgs/msg/NavSatFix", t, gps(k, _fix(t))))
        messages.sort(key=lambda item: item[2])
        bag = write_ros2(folder / "damaged", messages)
        if after is not None:
            after(bag)
        truth_topic = ["--truth-topic", "/truth"] if truth is not None else []
        # without corners: the checks are the reader's, and the front end is the time
        return ["bag", str(bag), *truth_topic, "--data", "corners=false"]

    return build


def _keep(k: int, message: object) -> object:
    return message


def _pose(t: float, x: float | None = None, w: float = 1.0):
    position = T["geometry_msgs/msg/Point"](x=0.1 * t if x is None else x, y=0.0, z=0.0)
    orientation = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=w)
    pose = T["geometry_msgs/msg/Pose"](position=position, orientation=orientation)
    return T["geometry_msgs/msg/PoseStamped"](header=_header(t), pose=pose)


def _fix(t: float, latitude: float = 48.137):
    return T["sensor_msgs/msg/NavSatFix"](
        header=_header(t),
        status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
        latitude=latitude,
        longitude=11.575,
        altitude=520.0,
        position_covariance=np.zeros(9),
        position_covariance_type=0,
    )


def _typed_cloud(x_type: str = "<f4", z_type: str = "<f4") -> Change:
    """Clouds whose coordinates are stored (and declared) in other types."""

    def change(k: int, message):
        points = _box_points(np.random.default_rng(k))
        records = np.zeros(len(points), dtype=[("x", x_type), ("y", "<f4"), ("z", z_type)])
        for axis, name in enumerate("xyz"):
            records[name] = points[:, axis]
        return encode_pointcloud2(TYPESTORE, message.header, records, is_dense=False)

    return change


def _field(k: int, message):
    """A cloud whose last field runs past the point."""
    fields = list(message.fields)
    fields[-1] = dataclasses.replace(fields[-1], offset=message.point_step - 2)
    return dataclasses.replace(message, fields=fields)


def _times(seconds: float) -> Change:
    """Clouds with a per-point time field, their last points timed ``seconds`` late."""

    def change(k: int, message):
        points = _box_points(np.random.default_rng(k))
        times = np.linspace(0.0, 0.09, len(points))
        times[-50:] = seconds
        return _cloud(1.0 + 0.1 * k, np.column_stack([points, times]), ("x", "y", "z", "time"))

    return change


def _truncate_messages(topic: str, indices: tuple[int, ...]) -> Callable[[Path], None]:
    """Cut the stored bytes of some messages of ``topic`` in the bag's sqlite3 storage."""

    def damage(bag: Path) -> None:
        storage = next(bag.glob("*.db3"))
        with sqlite3.connect(storage) as db:
            (topic_id,) = db.execute("SELECT id FROM topics WHERE name = ?", (topic,)).fetchone()
            rows = db.execute(
                "SELECT id FROM messages WHERE topic_id = ? ORDER BY timestamp", (topic_id,)
            ).fetchall()
            for index in indices:
                db.execute(
                    "UPDATE messages SET data = substr(data, 1, 40) WHERE id = ?", rows[index]
                )

    return damage


BROKEN = (2, 4)  # two of the five clouds (more than max_skipped_fraction = 5 %)
BAD_IMU = tuple(range(5, 50, 10))  # five of the fifty samples
BAG_CASES: list[tuple[str, Builder, str]] = [
    (
        "bag cloud x declared uint8",
        _bag(clouds=_typed_cloud(x_type="<u1")),
        "topic /cloud, t=1.000000000: PointCloud2 field 'x' is UINT8 (datatype 2)",
    ),
    (
        "bag cloud z declared int16",
        _bag(clouds=_typed_cloud(z_type="<i2")),
        "PointCloud2 field 'z' is INT16 (datatype 3); coordinates must be FLOAT32 or FLOAT64",
    ),
    (
        "bag clouds with row_step below the row",
        _bag(clouds=_at(BROKEN, lambda k, m: dataclasses.replace(m, row_step=m.row_step - 12))),
        "2 of the 5 messages on /cloud skipped (first: /cloud at t=1.200000000: malformed PointCloud2 (row_step",
    ),
    (
        "bag clouds with short data",
        _bag(clouds=_at(BROKEN, lambda k, m: dataclasses.replace(m, data=m.data[:-12]))),
        "messages on /cloud skipped (first: /cloud at t=1.200000000: malformed PointCloud2 (data has",
    ),
    (
        "bag clouds with a field past the point",
        _bag(clouds=_at(BROKEN, _field)),
        "malformed PointCloud2 (field 'z' (offset 10, 4 bytes) runs past point_step 12)",
    ),
    (
        "bag every cloud malformed",
        _bag(clouds=lambda k, m: dataclasses.replace(m, data=m.data[:-12])),
        "no cloud on /cloud sweeps inside the common time base",
    ),
    (
        "bag clouds beyond any lidar range",
        _bag(
            clouds=_at(
                BROKEN,
                lambda k, m: _cloud(1.0 + 0.1 * k, _box_points(np.random.default_rng(k)) * 1e5),
            )
        ),
        "2 of the 5 messages on /cloud skipped (first: /cloud at t=1.200000000: empty cloud",
    ),
    (
        "bag clouds with points timed seconds late",
        _bag(clouds=_at(BROKEN, _times(7.0))),
        "2 of the 5 messages on /cloud repaired (first: /cloud at t=1.200000000: implausible points dropped (50 of 2000",
    ),
    (
        "bag dense clouds with nan points",
        _bag(
            clouds=_at(
                BROKEN,
                lambda k, m: dataclasses.replace(
                    _cloud(
                        1.0 + 0.1 * k,
                        np.vstack([_box_points(np.random.default_rng(k)), np.full((3, 3), np.nan)]),
                    ),
                    is_dense=True,
                ),
            )
        ),
        "implausible points dropped (3 non-finite points in a dense cloud)",
    ),
    (
        "bag imu gyro beyond any gyro",
        _bag(imu=_at(BAD_IMU, lambda k, m: _imu(1.0 + 0.01 * k, 1e4))),
        "5 of the 50 messages on /imu skipped (first: /imu at t=1.050000000: implausible IMU sample",
    ),
    (
        "bag imu accel beyond any accelerometer",
        _bag(
            imu=_at(
                BAD_IMU,
                lambda k, m: dataclasses.replace(
                    m, linear_acceleration=T["geometry_msgs/msg/Vector3"](x=0.0, y=3e5, z=9.81)
                ),
            )
        ),
        "|accel| 3e+05 m/s^2",
    ),
    (
        "bag imu stamps jumping a day",
        _bag(imu=_at(BAD_IMU, lambda k, m: dataclasses.replace(m, header=_header(86400.0 + k)))),
        "messages on /imu skipped (first: /imu at t=1.050000000: header stamp more than 10 s off the record time",
    ),
    (
        "bag imu messages cut short",
        _bag(after=_truncate_messages("/imu", BAD_IMU)),
        "5 of the 50 messages on /imu skipped (first: /imu at t=1.050000000: cannot deserialize the message",
    ),
    (
        "bag truth quaternion not unit",
        _bag(truth=_at((4, 9, 20), lambda k, m: _pose(1.0 + 0.02 * k, w=3.0))),
        "3 of the 40 messages on /truth skipped (first: /truth at t=1.080000000: orientation not a unit quaternion (norm 3)",
    ),
    (
        "bag truth pose jumping",
        _bag(truth=_at((4, 9, 20), lambda k, m: _pose(1.0 + 0.02 * k, x=5000.0))),
        "messages on /truth skipped (first: /truth at t=1.080000000: pose jumps faster than 100 m/s",
    ),
    (
        "bag truth position beyond the planet",
        _bag(truth=_at((4, 9, 20), lambda k, m: _pose(1.0 + 0.02 * k, x=1e300))),
        "position beyond 1e+07 m",
    ),
    (
        "bag gps fix off the globe",
        _bag(gps=_at(BROKEN, lambda k, m: _fix(1.0 + 0.1 * k, latitude=412.0))),
        "2 of the 5 messages on /fix skipped (first: /fix at t=1.200000000: GPS fix off the globe",
    ),
]

CASES = TRAJECTORY_CASES + SCAN_CASES + BAG_CASES


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def earlier_bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, bytes]]:
    """A finished ``bag`` output folder every bag case is pointed at with --out (``bag``
    refuses a run folder as its --out)."""
    root = tmp_path_factory.mktemp("earlier_bag")
    argv = [*_bag()(root), "--estimator", "dead-reckoning", "--no-plots"]
    folder = root / "out"
    assert main([*argv, "--out", str(folder)]) == 0
    return folder, _snapshot(folder)


@pytest.mark.parametrize(("name", "build", "culprit"), CASES, ids=[c[0] for c in CASES])
def test_meaningless_input_is_one_clear_error_and_loses_nothing(
    name: str, build: Builder, culprit: str, tmp_path: Path, request, capsys
) -> None:
    argv = build(tmp_path)
    folder, before = (
        request.getfixturevalue(f"earlier_{argv[0]}") if argv[0] != "metrics" else (None, None)
    )
    if folder is not None:
        argv = [*argv, "--out", str(folder)]
    capsys.readouterr()
    status = main(argv)
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert status == 2, (status, captured.err)
    assert len(lines) == 1 and lines[0].startswith("error: "), lines  # one line, nothing else
    assert culprit in lines[0], lines[0]
    assert "Traceback" not in captured.err and "internal error" not in captured.err
    if folder is not None:
        assert _snapshot(folder) == before
        assert not [p for p in folder.parent.iterdir() if p.name.startswith(".")]


def test_the_corpus_covers_every_group() -> None:
    assert len(TRAJECTORY_CASES) >= 10 and len(SCAN_CASES) >= 15 and len(BAG_CASES) >= 15
    assert len({name for name, _, _ in CASES}) == len(CASES)


# ------------------------------------------------------------------------ flipped words
TOPIC = re.compile(r"/(points|imu|ground_truth)\b")
TOPIC_COUNT = re.compile(
    r"(skipped|repaired) \d+ x /(points|imu|ground_truth)\b|read \d+ of the \d+ messages"
)


@pytest.mark.parametrize("storage", ["ros1", "sqlite3", "mcap"])
def test_flipped_words_in_a_bag_are_never_silent(storage: str, tmp_path: Path, capsys) -> None:
    """20 random 8-byte words written over the middle of a bag's storage (where the clouds
    are): the run either stops with one error line naming a topic, or finishes and warns
    naming the topic and how many of its messages were skipped or repaired. Run once as it
    comes (here: an error, too many clouds repaired or missing), then with the thresholds
    raised to accept the damage (a finished run and the warnings)."""
    from datasets.synthetic_lidar import write_lidar_bag

    options = {"duration_s": "0.5", "columns": "256"}
    if storage == "ros1":
        bag = storage_file = write_lidar_bag(tmp_path / "corridor", 3, "ros1", options)
    else:
        bag = write_lidar_bag(tmp_path / "corridor", 3, "ros2", {**options, "storage": storage})
        storage_file = next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))
    data = bytearray(storage_file.read_bytes())
    rng = np.random.default_rng(40)
    for position in rng.integers(len(data) // 10, 8 * len(data) // 10, 20):
        data[position : position + 8] = rng.bytes(8)
    storage_file.write_bytes(bytes(data))
    accept = ["--data", "max_skipped_fraction=1", "--data", "max_missing_fraction=1"]
    for index, extra in enumerate(([], accept)):
        capsys.readouterr()
        argv = ["bag", str(bag), "--out", str(tmp_path / f"out{index}"), *extra]
        status = main([*argv, "--estimator", "dead-reckoning", "--no-plots"])
        err = capsys.readouterr().err
        assert "Traceback" not in err and "internal error" not in err
        if status == 2:
            errors = [line for line in err.splitlines() if line.startswith("error: ")]
            assert len(errors) == 1 and TOPIC.search(errors[0]), err
        else:
            assert status == 0, err
            warnings = [line for line in err.splitlines() if line.startswith("warning: ")]
            assert any(TOPIC_COUNT.search(line) for line in warnings), err
