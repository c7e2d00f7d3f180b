"""Dataset ``scans:FOLDER``: a folder of point clouds, one file per frame, ordered by name.

Formats: KITTI ``.bin`` (float32 x, y, z, intensity), ``.pcd`` (``DATA ascii`` or
``binary``; ``binary_compressed`` is refused with a clear error), ``.ply`` (``ascii`` or
``binary_little_endian``/``binary_big_endian`` vertex elements); suffixes in any case. One
file per frame: a frame index (the name without its suffix) present twice, in two formats,
is an error naming both files. Per-point times come from
a ``time``/``t``/``timestamp``/``offset_time`` field when a PCD/PLY has one (same unit rules
as bags, ``datasets.bags.pointcloud2``). Without one, whether the sweeps are
motion-compensated is decided at load from the first scans (option ``point_times=auto``, the
default; ``datasets.lidar.sweep_timing``): raw sweeps are timed by azimuth, with the spin
direction and start found in them (``datasets.lidar.sweep_times``), compensated ones are read
without times, and an undecided folder is read as compensated with a warning. The decision
and its evidence are ``Sequence.decisions`` (or a warning) and
``metadata["sweep_timing"]``; ``point_times=field`` or ``azimuth`` states it instead. Both
real KITTI clips in ``../shared/data`` are raw sweeps and are decided so. Read as
compensated, an uncompensated sweep shows as the corners disagreeing with KISS-ICP's
heading, which the run warns about (``LidarFrontEnd.heading_warning``).

Frame times: one number per line in ``times.txt`` (KITTI odometry) or ``timestamps.txt``
in the folder, or the file given by option ``timestamps``; otherwise ``index / rate_hz``.
Ground truth: an optional TUM file (option ``ground_truth``).
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
from pydantic import ConfigDict, Field

from datasets.bags.pointcloud2 import TIME_FIELDS, relative_point_seconds
from datasets.bags.sequence_sources import LidarSource
from datasets.errors import InputError
from datasets.lidar.frontend import LidarFrontEnd
from datasets.lidar.frontend_settings import LidarSourceOptions, describe_lidar_options
from datasets.lidar.frontend_stream import with_front_end
from datasets.lidar.kiss_icp_odometry import pose_time
from datasets.lidar.sweep_times import point_times_for
from datasets.lidar.sweep_timing import SweepTimingDecision, decide_sweep_timing
from datasets.measurements import PointCloud, Sensor
from datasets.options import build_model, nest_dotted
from datasets.pass_report import PassReport
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import GroundTruth, StateHistory
from datasets.text_files import text_lines
from datasets.trajectory_io import read_tum
from datasets.truth_quality.assess import assess_trajectory

SUFFIXES = (".bin", ".pcd", ".ply")
_PCD_TYPES = {
    ("F", 4): "f4",
    ("F", 8): "f8",
    ("U", 1): "u1",
    ("U", 2): "u2",
    ("U", 4): "u4",
    ("U", 8): "u8",
    ("I", 1): "i1",
    ("I", 2): "i2",
    ("I", 4): "i4",
    ("I", 8): "i8",
}
_PLY_TYPES = {
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
    "uchar": "u1",
    "uint8": "u1",
    "char": "i1",
    "int8": "i1",
    "ushort": "u2",
    "uint16": "u2",
    "short": "i2",
    "int16": "i2",
    "uint": "u4",
    "uint32": "u4",
    "int": "i4",
    "int32": "i4",
}


class ScanFolderOptions(LidarSourceOptions):
    """``--data`` options of ``scans:FOLDER``."""

    model_config = ConfigDict(extra="forbid")

    timestamps: str | None = Field(
        None,
        description="file with one frame time [s] per line (default: times.txt / timestamps.txt in the folder)",
    )
    rate_hz: float = Field(10.0, gt=0, description="frame rate when there is no timestamps file")
    ground_truth: str | None = Field(None, description="TUM file of true poses")


def _cloud_from_records(
    records: np.ndarray, names: tuple[str, ...], stamp: float, path: Path, time_unit: str
) -> tuple[np.ndarray, np.ndarray | None]:
    missing = [axis for axis in ("x", "y", "z") if axis not in names]
    if missing:
        raise InputError(
            f"{path}: no {'/'.join(missing)} field (fields: {', '.join(names) or 'none'})"
        )
    points = np.column_stack([records["x"], records["y"], records["z"]]).astype(np.float64)
    time_field = next((name for name in TIME_FIELDS if name in names), None)
    times = (
        relative_point_seconds(np.asarray(records[time_field]), stamp, time_unit)
        if time_field
        else None
    )
    finite = np.all(np.isfinite(points), axis=1) & (
        np.isfinite(times) if times is not None else True
    )
    return points[finite], (times[finite] if times is not None else None)


_NOT_TEXT = re.compile(rb"[^\t\n\r\x20-\x7e]")


def _ascii_table(
    path: Path, body: bytes, first_line: int, columns: int, rows: int, declared: str
) -> np.ndarray:
    """The first ``rows`` number rows of an ASCII point body, shape (rows, columns).

    Args:
        body: the bytes after the header, whose first line is ``first_line`` of the file.
        declared: what the header says a row holds (for messages), e.g. ``FIELDS x y z``.

    Raises:
        InputError: naming the file (and the line) for a binary body, a row with too few or
            too many values, a word where a number belongs, or fewer rows than declared.
    """
    binary = _NOT_TEXT.search(body)
    if binary:
        raise InputError(
            f"{path}: declared ascii, but its body holds binary bytes (0x{body[binary.start()]:02x} "
            f"at byte {binary.start()} after the header): a binary file with the wrong header?"
        )
    numbered = [
        (number, line.split())
        for number, line in enumerate(body.decode("ascii").splitlines(), start=first_line)
        if line.strip()
    ][:rows]
    if len(numbered) < rows:
        raise InputError(f"{path}: {len(numbered)} point rows, its header declares {rows}")
    for number, words in numbered:
        if len(words) != columns:
            raise InputError(
                f"{path}:{number}: {len(words)} values, its header declares {columns} ({declared})"
            )
    try:
        return np.array([words for _, words in numbered], dtype=float).reshape(rows, columns)
    except ValueError:  # find the word, to name its line
        for number, words in numbered:
            for word in words:
                try:
                    float(word)
                except ValueError:
                    raise InputError(f"{path}:{number}: '{word}' is not a number") from None
        raise


def read_bin(path: Path) -> np.ndarray:
    """KITTI velodyne scan: float32 (x, y, z, intensity) records -> (n, 3)."""
    blob = path.read_bytes()
    if len(blob) % 16:
        raise InputError(
            f"{path}: {len(blob)} bytes is not a whole number of KITTI points (16 bytes each)"
        )
    points = np.frombuffer(blob, dtype="<f4").reshape(-1, 4)[:, :3].astype(np.float64)
    return points[np.all(np.isfinite(points), axis=1)]


def read_pcd(
    path: Path, stamp: float, time_unit: str = "auto"
) -> tuple[np.ndarray, np.ndarray | None]:
    """PCD (ascii / binary) -> points (n, 3), per-point times or None."""
    blob = path.read_bytes()
    header: dict[str, list[str]] = {}
    offset = 0
    line_number = 0
    while True:
        end = blob.find(b"\n", offset)
        if end < 0:
            raise InputError(f"{path}: PCD header ends without a DATA line")
        line = blob[offset:end].decode("ascii", errors="replace").strip()
        offset = end + 1
        line_number += 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == "DATA":
            break
    names = tuple(header.get("FIELDS", ()))
    for key in ("SIZE", "TYPE", "COUNT"):
        # zip() would pair them silently short: a field read with another's size
        if len(header.get(key, names)) != len(names):
            raise InputError(
                f"{path}: PCD header declares {len(names)} FIELDS ({' '.join(names)}) but "
                f"{len(header.get(key, ()))} {key} values"
            )
    try:
        sizes = [int(v) for v in header["SIZE"]]
        kinds = header["TYPE"]
        counts = [int(v) for v in header.get("COUNT", ["1"] * len(names))]
        points_count = (
            int(header["POINTS"][0])
            if "POINTS" in header
            else int(header["WIDTH"][0]) * int(header.get("HEIGHT", ["1"])[0])
        )
    except (KeyError, ValueError, IndexError) as error:
        raise InputError(
            f"{path}: malformed PCD header ({type(error).__name__}: {error})"
        ) from None
    if points_count < 0 or min(counts, default=1) < 1:
        raise InputError(f"{path}: PCD header declares a negative POINTS or a COUNT below 1")
    unknown = [(n, k, z) for n, k, z in zip(names, kinds, sizes) if (k, z) not in _PCD_TYPES]
    if unknown:
        name, kind, size = unknown[0]
        raise InputError(f"{path}: PCD field '{name}' has TYPE {kind} SIZE {size}: no PCD type")
    formats = [
        (_PCD_TYPES[(kind, size)], (count,)) if count > 1 else _PCD_TYPES[(kind, size)]
        for kind, size, count in zip(kinds, sizes, counts)
    ]
    names = tuple(name if name != "_" else f"_pad{index}" for index, name in enumerate(names))
    mode = (header["DATA"] or ["(nothing)"])[0].lower()
    if mode == "ascii":
        columns = np.cumsum([0] + counts)
        table = _ascii_table(
            path,
            blob[offset:],
            line_number + 1,
            int(columns[-1]),
            points_count,
            f"FIELDS {' '.join(names)}",
        )
        records = {name: table[:, columns[k]] for k, name in enumerate(names)}
        return _cloud_from_records(records, names, stamp, path, time_unit)  # type: ignore[arg-type]
    if mode == "binary":
        dtype = np.dtype(
            {
                "names": list(names),
                "formats": ["<" + f if isinstance(f, str) else ("<" + f[0], f[1]) for f in formats],
            }
        )
        # an ascii body under DATA binary decodes to numbers that look like any others; binary
        # floats are never printable text for long (and PCL pads binary files with zeros)
        if points_count and not _NOT_TEXT.search(blob[offset : offset + 4096]):
            raise InputError(
                f"{path}: declared DATA binary, but its body is text: an ascii file with the "
                "wrong header?"
            )
        if len(blob) - offset < dtype.itemsize * points_count:
            raise InputError(
                f"{path}: PCD binary data is {len(blob) - offset} bytes, header declares {dtype.itemsize * points_count}"
            )
        records = np.frombuffer(blob, dtype=dtype, count=points_count, offset=offset)
        return _cloud_from_records(records, names, stamp, path, time_unit)
    raise InputError(f"{path}: PCD DATA {mode} is not supported (use ascii or binary)")


def read_ply(
    path: Path, stamp: float, time_unit: str = "auto"
) -> tuple[np.ndarray, np.ndarray | None]:
    """PLY (ascii / binary) vertex element -> points (n, 3), per-point times or None."""
    blob = path.read_bytes()
    end = blob.find(b"end_header")
    if not blob.startswith(b"ply") or end < 0:
        raise InputError(f"{path}: not a PLY file (no 'ply' magic or 'end_header')")
    newline = blob.find(b"\n", end)
    if newline < 0:
        raise InputError(f"{path}: PLY header's 'end_header' line does not end (no data)")
    body = newline + 1
    lines = blob[:end].decode("ascii", errors="replace").splitlines()
    fmt, count, names, formats, in_vertex, before = None, 0, [], [], False, 0
    for number, line in enumerate(lines, start=1):
        words = line.split()
        if not words:
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                in_vertex = words[1] == "vertex"
                if in_vertex:
                    count = int(words[2])
                elif not names:
                    before += 1
            elif words[0] == "property" and in_vertex:
                if words[1] == "list" or words[1] not in _PLY_TYPES:
                    raise InputError(
                        f"{path}:{number}: unsupported PLY vertex property '{' '.join(words[1:])}'"
                    )
                formats.append(_PLY_TYPES[words[1]])
                names.append(words[2])
        except (IndexError, ValueError):
            raise InputError(
                f"{path}:{number}: malformed PLY header line '{line.strip()}'"
            ) from None
    if count < 0:
        raise InputError(f"{path}: PLY header declares {count} vertices")
    if before:
        raise InputError(f"{path}: PLY elements before 'vertex' are not supported")
    if fmt == "ascii":
        table = _ascii_table(
            path,
            blob[body:],
            blob[:body].count(b"\n") + 1,
            len(names),
            count,
            f"properties {' '.join(names)}",
        )
        records = {name: table[:, k] for k, name in enumerate(names)}
        return _cloud_from_records(records, tuple(names), stamp, path, time_unit)  # type: ignore[arg-type]
    if fmt in ("binary_little_endian", "binary_big_endian"):
        order = "<" if fmt == "binary_little_endian" else ">"
        dtype = np.dtype({"names": names, "formats": [order + f for f in formats]})
        if len(blob) - body < dtype.itemsize * count:
            raise InputError(
                f"{path}: PLY data is {len(blob) - body} bytes, header declares {dtype.itemsize * count}"
            )
        records = np.frombuffer(blob, dtype=dtype, count=count, offset=body)
        return _cloud_from_records(records, tuple(names), stamp, path, time_unit)
    raise InputError(f"{path}: unknown PLY format '{fmt}'")


def read_scan(path: Path, stamp: float, time_unit: str = "auto") -> PointCloud:
    """One scan file -> ``PointCloud`` at ``stamp``."""
    suffix = path.suffix.lower()  # 000125.PCD is a PCD file too
    try:
        if suffix == ".bin":
            points, times = read_bin(path), None
        elif suffix == ".pcd":
            points, times = read_pcd(path, stamp, time_unit)
        else:
            points, times = read_ply(path, stamp, time_unit)
    except OSError as error:
        raise InputError(f"{path}: cannot read ({error})") from None
    return PointCloud(t=stamp, points=points, point_times=times)


def frame_times(folder: Path, files: list[Path], settings: ScanFolderOptions) -> np.ndarray:
    """Frame times [s] (module docstring); ``InputError`` for a bad or short timestamps file."""
    candidates = (
        [Path(settings.timestamps)]
        if settings.timestamps
        else [folder / "times.txt", folder / "timestamps.txt"]
    )
    for candidate in candidates:
        if candidate.is_file():
            values = []
            for number, line in text_lines(candidate, "timestamps file"):
                if line.strip() and not line.lstrip().startswith("#"):
                    try:
                        values.append(float(line.split()[0]))
                    except ValueError:
                        raise InputError(
                            f"{candidate}:{number}: not a time '{line.strip()}'"
                        ) from None
                    if not np.isfinite(values[-1]):
                        raise InputError(
                            f"{candidate}:{number}: time '{line.strip()}' is not finite"
                        )
            times = np.array(values)
            if len(times) < len(files):
                raise InputError(f"{candidate}: {len(times)} times for {len(files)} scans")
            return times[: len(files)]
        if settings.timestamps:
            raise InputError(f"{candidate}: no such timestamps file")
    return np.arange(len(files)) / settings.rate_hz


def load_scans(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """``scans:FOLDER`` -> ``Sequence`` with POINT_CLOUD, ODOMETRY, LANDMARKS."""
    return scans_sequence(
        argument, build_model(ScanFolderOptions, nest_dotted(options), f"scans:{argument}")
    )[0]


def scans_sequence(
    argument: str | None, settings: ScanFolderOptions
) -> tuple[Sequence, LidarSource]:
    """The sequence of a scan folder and its ``LidarSource``."""
    if not argument:
        raise InputError("dataset scans needs a folder: scans:FOLDER")
    folder = Path(argument)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder")
    files = sorted(path for path in folder.iterdir() if path.suffix.lower() in SUFFIXES)
    if not files:
        raise InputError(f"{folder}: no .bin, .pcd or .ply scans")
    seen: dict[str, Path] = {}
    for path in files:  # each file is one frame: one index twice would be read twice
        first = seen.setdefault(path.stem, path)
        if first is not path:
            raise InputError(
                f"{folder}: frame {path.stem} is there twice, as {first.name} and {path.name}; "
                "keep one"
            )
    times = frame_times(folder, files, settings)
    steps = np.diff(times)
    order_problem = np.flatnonzero(steps <= 0)
    # one sweep is one frame interval
    sweep_s = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1.0 / settings.rate_hz
    timing = folder_sweep_timing(files, times, settings, sweep_s)
    azimuth_sweep_s = timing.azimuth  # an AzimuthSweep when the clouds are timed by azimuth
    front_end = LidarFrontEnd(settings.front_end_settings())
    source = LidarSource(front_end)

    def clouds():
        report = source.report = type(source.report)()
        last = -np.inf
        for path, stamp in zip(files, times):
            if stamp <= last:
                report.skip(
                    str(folder), f"time not after the previous scan ({path.name})", float(stamp)
                )
                continue
            cloud = read_scan(path, float(stamp), settings.point_time_unit)
            if len(cloud.points) == 0:
                report.skip(str(folder), f"empty scan ({path.name})", float(stamp))
                continue
            if azimuth_sweep_s is not None:
                derived = point_times_for(
                    cloud.points, cloud.point_times, azimuth_sweep_s, str(path)
                )
                cloud = replace(cloud, point_times=derived)
            last = stamp
            yield cloud

    # filled once the stream has run: the KISS-ICP settings used, the corner_tracking
    # figures, the stream's skips and the front end's heading warning
    pass_report = PassReport.expecting("kiss_icp", "corner_reobservation")
    # Sequence.warnings (printed, and in every run's metrics.json): an undecided sweep
    # timing, an untrusted stretch of the truth
    warnings: list[str] = list(timing.warnings)

    # the sequence starts at the front end's first pose (the first kept scan's; its sweep's
    # end when it is deskewed), where the first odometry increment starts; datasets.bags
    # .reader.start_at_first_pose says why. Read also without deskewing: an empty or
    # out-of-order first file is skipped, and the start is then a later file's stamp.
    first = next(clouds(), None) if settings.odometry else None
    start = (
        float(times[0])
        if first is None
        else pose_time(first.t, first.point_times, settings.kiss.deskew)
    )

    def stream():
        yield from with_front_end(
            clouds(), front_end, settings.point_clouds, settings.max_frames, emit_from_s=start
        )
        pass_report.record(
            source.pass_warnings(),
            kiss_icp=front_end.resolved(),
            corner_reobservation=front_end.tracker.stats.summary(),
        )

    ground_truth = None
    if settings.ground_truth:
        pose = read_tum(settings.ground_truth)
        # where the TUM truth cannot be trusted is excluded from the scoring, and said
        excluded, lines = assess_trajectory(
            pose.t, pose.positions, pose.rotations, f"truth file {settings.ground_truth}"
        )
        warnings.extend(lines)
        ground_truth = GroundTruth(history=StateHistory(pose=pose), excluded=excluded)
    sensors = (
        ({Sensor.POINT_CLOUD} if settings.point_clouds else set())
        | ({Sensor.ODOMETRY} if settings.odometry else set())
        | ({Sensor.LANDMARKS} if settings.corners else set())
    )
    return Sequence(
        name=f"scans:{argument}",
        dimension=3,
        sensors=frozenset(sensors),
        stream=stream,
        ground_truth=ground_truth,
        noise=NoiseSpec(
            landmark_sigma_m=settings.corner.range_sigma_m, rate_hz={"lidar": settings.rate_hz}
        ),
        initial_state=InitialState(
            t=start, position=np.zeros(3), rotation=np.array([1.0, 0.0, 0.0, 0.0])
        ),
        # the front end's trajectory, increment covariances and counters, filled by the pass
        # (a folder of clouds has no other motion input)
        front_end=front_end.report if settings.odometry else None,
        metadata={
            "source": str(folder),
            "files": len(files),
            "time_order_problems": int(order_problem.size),
            "options": settings.model_dump(mode="json"),
            "sweep_timing": timing.as_dict(),
        },
        reference_source=f"TUM file {settings.ground_truth}" if settings.ground_truth else None,
        warnings=tuple(warnings),
        # what the loader decided and why, to print as notes (a clear decision) beside
        # the warnings (datasets.lidar.sweep_timing)
        decisions=(timing.text,) if timing.clear else (),
        pass_report=pass_report,
    ), source


def folder_sweep_timing(
    files: list[Path], times: np.ndarray, settings: ScanFolderOptions, sweep_s: float
) -> SweepTimingDecision:
    """How the folder's clouds are timed (``datasets.lidar.sweep_timing``), from its first
    ``settings.sweep.frames`` non-empty scans in time order (none read for
    ``point_times=field``)."""
    clouds: list[PointCloud] = []
    if settings.point_times != "field":
        last = -np.inf
        for path, stamp in zip(files, times):
            if len(clouds) >= settings.sweep.frames:
                break
            if stamp <= last:
                continue
            cloud = read_scan(path, float(stamp), settings.point_time_unit)
            if len(cloud.points):
                clouds.append(cloud)
                last = stamp
    return decide_sweep_timing(clouds, sweep_s, settings.point_times, settings.sweep)


def describe() -> list[str]:
    """Option lines for ``workbench list --verbose``."""
    return describe_lidar_options(ScanFolderOptions)
