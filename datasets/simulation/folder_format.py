"""A plain-text folder holding one sequence and its ground truth (``workbench simulate``).

Written deterministically (fixed float formats, sorted JSON keys, no time stamps), so the
same seed gives byte-identical files. ``README.md`` inside the folder documents each file
(the text is ``FOLDER_README`` below). Supported measurements: ``ImuSample``,
``GyroSample`` and ``LandmarkScan`` (the simulator's); other kinds raise ``InputError``.
"""

from __future__ import annotations

import dataclasses
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from datasets.errors import InputError
from datasets.measurements import GyroSample, ImuSample, LandmarkScan, Measurement, Sensor
from datasets.odometry_noise import OdometryNoiseModel
from datasets.sequence import InitialState, NoiseSpec, Sequence, split_description
from datasets.sighting_correlation import Autocorrelation, SightingCorrelation
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory
from datasets.trajectory_io import format_tum, read_tum, write_atomic

FORMAT_NAME = "workbench-sequence-folder"
FORMAT_VERSION = 1
TIME_FORMAT = "%.9f"
VALUE_FORMAT = "%.17g"  # shortest exact: values round-trip bit for bit

FOLDER_README = """\
# Sequence folder (format {format_name} v{format_version})

Written by `workbench simulate` (datasets/simulation/folder_format.py) and read back by
`read_sequence_folder`. Same scenario and seed give byte-identical files. Conventions:
time in seconds; world frame z-up; quaternions Hamilton body-to-world; body-frame
landmark p = R^T (rho - r); IMU bias convention measured = true + bias; CSV files have one
header line, comma-separated; times printed `%.9f`, values `%.17g` (exact round trip).

| file | content |
|---|---|
| `sequence.json` | name, dimension (2 or 3), sensors, noise spec (continuous-time IMU densities), initial state, whether ids are withheld, metadata (source, scenario, seed, resolved options) |
| `imu.csv` | 3-D IMU: `t, gyro_x, gyro_y, gyro_z` [rad/s], `accel_x, accel_y, accel_z` [m/s^2, specific force] |
| `gyro.csv` | planar rate gyro: `t, rate_z` [rad/s] |
| `scans.csv` | every landmark scan, also empty ones: `scan, t, count` |
| `landmarks.csv` | one row per observed landmark: `scan, t, id` (-1 when ids are withheld), body-frame position `x, y[, z]` [m], covariance upper triangle row by row `c_xx, c_xy[, c_xz], c_yy[, c_yz][, c_zz]` [m^2], and when `direction_count` j > 0 in `sequence.json`, j unit line directions `u1_x, u1_y[, u1_z], ...` (body frame) |
| `known_landmarks.csv` | surveyed landmarks in anchor preference order: `rank, id, x, y[, z]` (world) |
| `ground_truth/pose.tum` | true pose at the inertial rate, TUM `t x y z qx qy qz qw` (planar: z = 0, yaw) |
| `ground_truth/states.csv` | `t`, world velocity `vw_*`, body velocity `vb_*`, gyro bias `bg_*`, accelerometer bias `ba_*` (3-D only) |
| `ground_truth/landmarks.csv` | true world map `id, x, y[, z]` |
| `ground_truth/scan_ids.csv` | true id of every observation, same rows as `landmarks.csv`: `scan, t, id` |

Empty scans (no landmark visible) are kept in `scans.csv` with count 0, so readers see
every sensor tick.
"""


def _axes(dimension: int) -> list[str]:
    return ["x", "y", "z"][:dimension]


def _table(header: list[str], columns: list[np.ndarray], formats: list[str]) -> str:
    """CSV text: one header line, then rows formatted column by column."""
    buffer = io.StringIO()
    buffer.write(",".join(header) + "\n")
    if columns and len(columns[0]):
        table = np.column_stack([np.asarray(column, dtype=float) for column in columns])
        np.savetxt(buffer, table, fmt=formats, delimiter=",")
    return buffer.getvalue()


def _upper_triangle(dimension: int) -> tuple[np.ndarray, np.ndarray]:
    return np.triu_indices(dimension)


def _json_ready(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {str(key): _json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(item) for item in value]
    return value


def write_sequence_folder(sequence: Sequence, out_dir: str | Path) -> Path:
    """Write ``sequence`` into ``out_dir`` (created if needed); returns the folder path.

    Every file is written atomically, ``sequence.json`` (what makes the folder a sequence)
    removed first and written last; when a write fails (a full disk) the files this call wrote are removed again, so
    no partial sequence is left, and the error names the file. Raises ``InputError`` for
    measurement kinds the format does not hold.
    """
    folder = Path(out_dir)
    d = sequence.dimension
    axes = _axes(d)
    imu_rows, gyro_rows, scans = [], [], []
    for measurement in sequence.measurements():
        if isinstance(measurement, ImuSample):
            imu_rows.append(np.concatenate([[measurement.t], measurement.gyro, measurement.accel]))
        elif isinstance(measurement, GyroSample):
            gyro_rows.append(np.concatenate([[measurement.t], np.ravel(measurement.rate)]))
        elif isinstance(measurement, LandmarkScan):
            scans.append(measurement)
        else:
            raise InputError(
                f"{folder}: the sequence folder format cannot hold {type(measurement).__name__} measurements"
            )
    ids_withheld = any(scan.ids is None for scan in scans)
    files: dict[str, str] = {}

    if imu_rows:
        table = np.array(imu_rows)
        files["imu.csv"] = _table(
            ["t", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"],
            list(table.T),
            [TIME_FORMAT] + [VALUE_FORMAT] * 6,
        )
    if gyro_rows:
        table = np.array(gyro_rows)
        files["gyro.csv"] = _table(["t", "rate_z"], list(table.T), [TIME_FORMAT, VALUE_FORMAT])

    rows, cols = _upper_triangle(d)
    cov_names = [f"c_{axes[i]}{axes[j]}" for i, j in zip(rows, cols)]
    scan_index = np.concatenate(
        [np.full(scan.count, index) for index, scan in enumerate(scans)] or [np.zeros(0)]
    )
    scan_t = np.concatenate([np.full(scan.count, scan.t) for scan in scans] or [np.zeros(0)])
    points = np.concatenate([scan.points.reshape(-1, d) for scan in scans] or [np.zeros((0, d))])
    covariances = np.concatenate(
        [scan.covariances.reshape(-1, d, d) for scan in scans] or [np.zeros((0, d, d))]
    )
    ids = np.concatenate(
        [np.full(scan.count, -1) if scan.ids is None else np.asarray(scan.ids) for scan in scans]
        or [np.zeros(0)]
    )
    files["scans.csv"] = _table(
        ["scan", "t", "count"],
        [
            np.arange(len(scans)),
            np.array([scan.t for scan in scans]),
            np.array([scan.count for scan in scans]),
        ],
        ["%d", TIME_FORMAT, "%d"],
    )
    direction_count = _direction_count(scans, folder)
    direction_names = [f"u{m + 1}_{axis}" for m in range(direction_count) for axis in axes]
    directions = np.zeros((len(points), 0))
    if direction_count:
        directions = np.concatenate(
            [scan.directions.reshape(scan.count, direction_count * d) for scan in scans]
        )
    files["landmarks.csv"] = _table(
        ["scan", "t", "id", *axes, *cov_names, *direction_names],
        [scan_index, scan_t, ids, *points.T, *covariances[:, rows, cols].T, *directions.T],
        ["%d", TIME_FORMAT, "%d"] + [VALUE_FORMAT] * (d + len(cov_names) + len(direction_names)),
    )
    if sequence.known_landmarks is not None:
        known = sequence.known_landmarks
        files["known_landmarks.csv"] = _table(
            ["rank", "id", *axes],
            [np.arange(len(known)), known.ids, *known.positions.T],
            ["%d", "%d"] + [VALUE_FORMAT] * d,
        )

    truth = sequence.ground_truth
    if truth is not None:
        files.update(_ground_truth_files(truth, d, scans))

    initial = sequence.initial_state
    description = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "name": sequence.name,
        "dimension": d,
        "sensors": sorted(str(sensor) for sensor in sequence.sensors),
        "ids_withheld": ids_withheld,
        "direction_count": direction_count,
        "noise": _json_ready(dataclasses.asdict(sequence.noise)),
        "initial_state": None if initial is None else _json_ready(dataclasses.asdict(initial)),
        "metadata": _json_ready(sequence.description()),
        "files": sorted(files),
    }
    files["sequence.json"] = json.dumps(description, sort_keys=True, indent=2) + "\n"
    files["README.md"] = FOLDER_README.format(
        format_name=FORMAT_NAME, format_version=FORMAT_VERSION
    )
    # sequence.json goes first and comes back last: a folder that has one is complete, even
    # after a failed rewrite of an earlier sequence
    (folder / "sequence.json").unlink(missing_ok=True)
    written: list[Path] = []
    try:
        for name in sorted(files, key=lambda name: name == "sequence.json"):
            target = folder / name
            write_atomic(target, files[name])
            written.append(target)
    except BaseException as error:
        for path in written:
            path.unlink(missing_ok=True)
        for sub in {path.parent for path in written} - {folder}:
            if sub.is_dir() and not any(sub.iterdir()):  # ground_truth/, made by this call
                sub.rmdir()
        if isinstance(error, OSError) and error.filename is None:
            # a failed write() names no file: name the one being written
            raise OSError(error.errno, error.strerror, str(target)) from error
        raise
    return folder


def _direction_count(scans: list[LandmarkScan], folder: Path) -> int:
    """Line directions per landmark (j), the same for every scan, or 0 when none has them."""
    counts = {
        0 if scan.directions is None else int(scan.directions.shape[1])
        for scan in scans
        if scan.count
    }
    if any(scan.directions is not None for scan in scans) and any(
        scan.directions is None for scan in scans
    ):
        raise InputError(f"{folder}: some scans carry line directions and others not")
    if len(counts) > 1:
        raise InputError(
            f"{folder}: scans carry different numbers of line directions {sorted(counts)}"
        )
    return counts.pop() if counts else 0


def _ground_truth_files(truth: GroundTruth, d: int, scans: list[LandmarkScan]) -> dict[str, str]:
    files: dict[str, str] = {}
    axes = _axes(d)
    pose = truth.history.pose
    if pose is not None:
        files["ground_truth/pose.tum"] = "# timestamp tx ty tz qx qy qz qw\n" + format_tum(pose)
        header, columns = ["t"], [pose.t]
        named_blocks = [
            ("vw", truth.history.block(BlockName.VELOCITY)),
            ("vb", truth.body_velocity),
            ("bg", truth.history.block(BlockName.GYRO_BIAS)),
            ("ba", truth.history.block(BlockName.ACCEL_BIAS)),
        ]
        for prefix, block in named_blocks:
            if block is None or len(block.t) != len(pose.t):
                continue
            width = block.values.shape[1]
            names = axes if width == d else ["z"] if width == 1 else _axes(width)
            header += [f"{prefix}_{axis}" for axis in names]
            columns += list(block.values.T)
        files["ground_truth/states.csv"] = _table(
            header, columns, [TIME_FORMAT] + [VALUE_FORMAT] * (len(header) - 1)
        )
    if truth.landmarks is not None:
        files["ground_truth/landmarks.csv"] = _table(
            ["id", *axes],
            [truth.landmarks.ids, *truth.landmarks.positions.T],
            ["%d"] + [VALUE_FORMAT] * d,
        )
    if truth.scan_ids:
        scan_index = np.concatenate(
            [np.full(len(ids), index) for index, (_, ids) in enumerate(truth.scan_ids)]
        )
        scan_t = np.concatenate([np.full(len(ids), t) for t, ids in truth.scan_ids])
        true_ids = np.concatenate([np.asarray(ids) for _, ids in truth.scan_ids])
        files["ground_truth/scan_ids.csv"] = _table(
            ["scan", "t", "id"], [scan_index, scan_t, true_ids], ["%d", TIME_FORMAT, "%d"]
        )
    return files


def _read_table(
    path: Path, expected_header: list[str] | None = None
) -> tuple[list[str], np.ndarray]:
    """Header and float rows (n, columns) of a CSV file; ``InputError`` naming the file."""
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    lines = path.read_text().splitlines()
    if not lines:
        raise InputError(f"{path}: empty file (expected a header line)")
    header = lines[0].split(",")
    if expected_header is not None and header != expected_header:
        raise InputError(f"{path}:1: header {header} differs from the expected {expected_header}")
    rows = []
    for line_number, line in enumerate(lines[1:], start=2):
        fields = line.split(",")
        if len(fields) != len(header):
            raise InputError(f"{path}:{line_number}: {len(fields)} fields, expected {len(header)}")
        try:
            rows.append([float(field) for field in fields])
        except ValueError:
            raise InputError(f"{path}:{line_number}: not a number in '{line}'") from None
    table = np.array(rows, dtype=float).reshape(len(rows), len(header))
    if not np.all(np.isfinite(table)):
        raise InputError(f"{path}: non-finite value")
    return header, table


def read_sequence_folder(path: str | Path) -> Sequence:
    """Read a folder written by ``write_sequence_folder`` back into a ``Sequence``."""
    folder = Path(path)
    description_path = folder / "sequence.json"
    if not description_path.is_file():
        raise InputError(f"{folder}: not a sequence folder (no sequence.json)")
    try:
        description = json.loads(description_path.read_text())
        d = int(description["dimension"])
        name = description["name"]
        sensors = frozenset(Sensor(value) for value in description["sensors"])
        ids_withheld = bool(description["ids_withheld"])
        direction_count = int(description.get("direction_count", 0))
        files = set(description["files"])
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
        raise InputError(f"{description_path}: malformed description ({error})") from None
    if description.get("format") != FORMAT_NAME or d not in (2, 3):
        raise InputError(f"{description_path}: not a {FORMAT_NAME} description of dimension 2 or 3")
    axes = _axes(d)
    rows, cols = _upper_triangle(d)
    cov_names = [f"c_{axes[i]}{axes[j]}" for i, j in zip(rows, cols)]

    inertial: list[Measurement] = []
    if "imu.csv" in files:
        _, table = _read_table(
            folder / "imu.csv", ["t", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
        )
        inertial = [
            ImuSample(t=float(row[0]), gyro=row[1:4].copy(), accel=row[4:7].copy()) for row in table
        ]
    if "gyro.csv" in files:
        _, table = _read_table(folder / "gyro.csv", ["t", "rate_z"])
        inertial = [GyroSample(t=float(row[0]), rate=row[1:2].copy()) for row in table]
    _, scan_table = _read_table(folder / "scans.csv", ["scan", "t", "count"])
    direction_names = [f"u{m + 1}_{axis}" for m in range(direction_count) for axis in axes]
    _, observations = _read_table(
        folder / "landmarks.csv", ["scan", "t", "id", *axes, *cov_names, *direction_names]
    )
    covariance_columns = slice(3 + d, 3 + d + len(cov_names))
    direction_columns = slice(3 + d + len(cov_names), None)
    counts = scan_table[:, 2].astype(int)
    if counts.sum() != len(observations):
        raise InputError(
            f"{folder / 'landmarks.csv'}: {len(observations)} rows, scans.csv counts {counts.sum()}"
        )
    bounds = np.concatenate([[0], np.cumsum(counts)])
    scans = []
    for index, (t, start, stop) in enumerate(zip(scan_table[:, 1], bounds[:-1], bounds[1:])):
        block = observations[start:stop]
        if np.any(block[:, 0] != index):
            raise InputError(f"{folder / 'landmarks.csv'}: rows of scan {index} out of order")
        covariances = np.zeros((len(block), d, d))
        covariances[:, rows, cols] = block[:, covariance_columns]
        covariances[:, cols, rows] = block[:, covariance_columns]
        scans.append(
            LandmarkScan(
                t=float(t),
                points=block[:, 3 : 3 + d].copy(),
                covariances=covariances,
                ids=None if ids_withheld else block[:, 2].astype(int),
                directions=block[:, direction_columns].reshape(-1, direction_count, d).copy()
                if direction_count
                else None,
            )
        )

    known = None
    if "known_landmarks.csv" in files:
        _, table = _read_table(folder / "known_landmarks.csv", ["rank", "id", *axes])
        known = LandmarkMap(
            ids=table[:, 1].astype(int), positions=table[:, 2:].reshape(-1, d), frame=Frame.WORLD
        )

    truth = _read_ground_truth(folder, files, d, scan_table)
    noise_fields = description.get("noise") or {}
    initial = description.get("initial_state")
    initial_state = None
    if initial is not None:
        initial_state = InitialState(
            t=float(initial["t"]),
            position=np.array(initial["position"], dtype=float),
            rotation=np.array(initial["rotation"], dtype=float),
            velocity=None
            if initial["velocity"] is None
            else np.array(initial["velocity"], dtype=float),
            position_sigma_m=float(initial["position_sigma_m"]),
            rotation_sigma_rad=float(initial["rotation_sigma_rad"]),
            velocity_sigma_m_s=float(initial["velocity_sigma_m_s"]),
        )
    measurements = inertial + scans
    keys = np.array([m.t for m in measurements])
    priority = np.concatenate([np.zeros(len(inertial)), np.ones(len(scans))])
    order = np.lexsort((priority, keys))

    def stream():
        for index in order:
            yield dataclasses.replace(measurements[index])

    metadata, typed = split_description(description.get("metadata") or {})
    return Sequence(
        name=name,
        dimension=d,
        sensors=sensors,
        stream=stream,
        ground_truth=truth,
        noise=_noise_spec(noise_fields),
        initial_state=initial_state,
        known_landmarks=known,
        metadata=metadata,
        landmark_ids=not ids_withheld,
        **typed,
    )


def _noise_spec(fields: dict) -> NoiseSpec:
    """``NoiseSpec`` from its ``sequence.json`` form (``dataclasses.asdict``: the nested
    models come back as dicts)."""
    fields = dict(fields)
    odometry = fields.get("odometry")
    if isinstance(odometry, dict):
        fields["odometry"] = OdometryNoiseModel(
            np.array(odometry["rates"], dtype=float), odometry.get("source", "")
        )
    correlation = fields.get("sighting_correlation")
    if isinstance(correlation, dict):
        fields["sighting_correlation"] = SightingCorrelation(
            Autocorrelation(**correlation["radial"]),
            Autocorrelation(**correlation["tangential"]),
            correlation.get("source", ""),
        )
    return NoiseSpec(**fields)


def _read_ground_truth(
    folder: Path, files: set[str], d: int, scan_table: np.ndarray
) -> GroundTruth | None:
    if "ground_truth/pose.tum" not in files:
        return None
    spatial = read_tum(folder / "ground_truth/pose.tum")
    if d == 3:
        pose = spatial
    else:
        quats = spatial.rotations
        pose = Trajectory(
            t=spatial.t,
            positions=spatial.positions[:, :2],
            rotations=2 * np.arctan2(quats[:, 3], quats[:, 0]),
        )
    blocks: dict[BlockName, StateBlock] = {}
    body_velocity = None
    if "ground_truth/states.csv" in files:
        header, table = _read_table(folder / "ground_truth/states.csv")

        def columns(prefix: str) -> np.ndarray | None:
            picked = [index for index, name in enumerate(header) if name.startswith(prefix + "_")]
            return table[:, picked] if picked else None

        t = table[:, 0]
        for prefix, block_name, frame in (
            ("vw", BlockName.VELOCITY, Frame.WORLD),
            ("bg", BlockName.GYRO_BIAS, Frame.BODY),
            ("ba", BlockName.ACCEL_BIAS, Frame.BODY),
        ):
            values = columns(prefix)
            if values is not None:
                blocks[block_name] = StateBlock(t=t, values=values, frame=frame)
        body = columns("vb")
        body_velocity = None if body is None else StateBlock(t=t, values=body, frame=Frame.BODY)
    landmarks = None
    if "ground_truth/landmarks.csv" in files:
        _, table = _read_table(folder / "ground_truth/landmarks.csv")
        landmarks = LandmarkMap(
            ids=table[:, 0].astype(int), positions=table[:, 1:].reshape(-1, d), frame=Frame.WORLD
        )
    scan_ids: tuple[tuple[float, np.ndarray], ...] = ()
    if "ground_truth/scan_ids.csv" in files:
        _, table = _read_table(folder / "ground_truth/scan_ids.csv", ["scan", "t", "id"])
        scan_column = table[:, 0]
        if np.any(np.diff(scan_column) < 0):
            raise InputError(f"{folder / 'ground_truth/scan_ids.csv'}: rows not grouped by scan")
        indices = np.arange(len(scan_table))
        starts, stops = (
            np.searchsorted(scan_column, indices, "left"),
            np.searchsorted(scan_column, indices, "right"),
        )
        scan_ids = tuple(
            (float(t), table[start:stop, 2].astype(int))
            for t, start, stop in zip(scan_table[:, 1], starts, stops)
        )
    return GroundTruth(
        history=StateHistory(pose=pose, blocks=blocks),
        landmarks=landmarks,
        body_velocity=body_velocity,
        scan_ids=scan_ids,
    )
