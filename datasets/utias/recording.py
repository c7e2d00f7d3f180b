"""One robot's MRCLAM files as streams on one time base: odometry, Vicon truth (headings
repaired, its untrusted intervals found by ``datasets.truth_quality``) and sighting times
(``datasets.utias``).

``read_recording`` is what the loader and the calibration of the *other* robots share; it
is cached per process on the files' identity (path, size, modification time) and the
options that shape it, because a sweep loads the same folder many times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from datasets.errors import InputError
from datasets.odometry_calibration import Increments
from datasets.rotations import wrap_angle
from datasets.truth_quality.assess import assess_truth
from datasets.truth_quality.quality import TruthQuality
from datasets.utias.tables import Table, first_backward, grid_times, increasing, read_table

ROBOT_FILES = ("Odometry", "Groundtruth", "Measurement")


@dataclass(frozen=True)
class Recording:
    """One robot's rows on a common time base (seconds from ``origin``).

    Attributes:
        folder, robot: where it comes from.
        identity: the three files' (size, modification time): a changed file is another
            recording (caches key on it).
        odometry, truth, sightings: the parsed files (line numbers for messages).
        time_source: ``row_grid`` (row index x grid step) or ``printed``.
        origin: the printed time of the base's zero [s].
        odo_t (n,) [s], odo_values (n, 2): commanded (forward velocity [m/s], turn rate
            [rad/s]) as recorded, no calibration applied.
        truth_t (m,) [s], truth_xy (m, 2) [m], truth_heading (m,) [rad]: Vicon, headings
            repaired (``repair_heading_glitches``) over the whole recording.
        truth_heading_raw (m,) [rad]: the headings as printed.
        heading_samples_repaired: how many headings the repair replaced.
        truth_quality: where the Vicon cannot be trusted (``datasets.truth_quality``:
            dropouts, freezes, jumps, wrong tracks, headings against the direction of
            travel, motion the odometry contradicts), judged on the repaired headings
            against the raw odometry. Neither scored nor fitted on.
        meas_t (k,) [s]: the sightings' times on the base (snapped to the grid on grid data).
        counts: rows dropped because their time did not increase (printed times only).
    """

    folder: Path
    robot: int
    identity: tuple
    odometry: Table
    truth: Table
    sightings: Table
    time_source: str
    origin: float
    odo_t: np.ndarray
    odo_values: np.ndarray
    truth_t: np.ndarray
    truth_xy: np.ndarray
    truth_heading: np.ndarray
    truth_heading_raw: np.ndarray
    heading_samples_repaired: int
    truth_quality: TruthQuality
    meas_t: np.ndarray
    counts: dict[str, int]

    @property
    def name(self) -> str:
        return f"utias:{self.folder}#robot{self.robot}"

    def vicon(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times (m,), positions (m, 2), repaired headings (m,)) of the whole recording,
        without the samples ``truth_quality`` excludes (what a calibration may fit on)."""
        keep = self.truth_quality.keep_mask(self.truth_t)
        return self.truth_t[keep], self.truth_xy[keep], self.truth_heading[keep]


def robots_in(folder: Path) -> list[int]:
    """The robots of an MRCLAM folder: every N with all three ``RobotN_*.dat`` files."""
    found = []
    for path in Path(folder).glob("Robot*_Odometry.dat"):
        number = path.name[len("Robot") : -len("_Odometry.dat")]
        if number.isdigit() and all(
            (Path(folder) / f"Robot{number}_{kind}.dat").is_file() for kind in ROBOT_FILES
        ):
            found.append(int(number))
    return sorted(found)


def read_recording(
    folder: Path,
    robot: int,
    grid_step_s: float,
    max_dropped_fraction: float,
    max_heading_rate_rad_s: float,
    max_speed_m_s: float,
) -> Recording:
    """Robot ``robot``'s recording in ``folder`` (module docstring; cached)."""
    folder = Path(folder).resolve()
    return _read_recording(
        folder,
        robot,
        robot_identity(folder, robot),
        grid_step_s,
        max_dropped_fraction,
        max_heading_rate_rad_s,
        max_speed_m_s,
    )


def robot_identity(folder: Path, robot: int) -> tuple:
    """The (size, modification time) of a robot's three files: what ``read_recording``
    caches on, without reading them."""
    folder = Path(folder).resolve()
    return tuple(_file_identity(folder / f"Robot{robot}_{kind}.dat") for kind in ROBOT_FILES)


def _file_identity(path: Path) -> tuple[int, int] | None:
    try:
        status = path.stat()
    except OSError:
        return None  # read_table names the file
    return status.st_size, status.st_mtime_ns


@lru_cache(maxsize=16)
def _read_recording(
    folder: Path,
    robot: int,
    identity: tuple,
    step: float,
    max_dropped_fraction: float,
    max_heading_rate_rad_s: float,
    max_speed_m_s: float,
) -> Recording:
    name = f"utias:{folder}#robot{robot}"
    counts: dict[str, int] = {}
    odometry = read_table(folder / f"Robot{robot}_Odometry.dat", ("time", "v", "omega"))
    truth = read_table(folder / f"Robot{robot}_Groundtruth.dat", ("time", "x", "y", "heading"))
    sightings = read_table(
        folder / f"Robot{robot}_Measurement.dat", ("time", "barcode", "range", "bearing")
    )
    odo_grid = grid_times(odometry.values[:, 0], step, odometry.first_decimals)
    truth_grid = grid_times(truth.values[:, 0], step, truth.first_decimals)
    if odo_grid is not None and truth_grid is not None:
        time_source = "row_grid"
        odo_t, odo_values = odo_grid, odometry.values[:, 1:]
        truth_t, truth_values = truth_grid, truth.values[:, 1:]
        origin = min(odo_t[0], truth_t[0])
        meas_t = np.round((sightings.values[:, 0] - origin) / step) * step + origin
    else:
        time_source = "printed"
        odo_t, odo_values, counts["odometry_time_not_increasing"] = increasing(
            odometry.values[:, 0], odometry.values[:, 1:]
        )
        truth_t, truth_values, counts["groundtruth_time_not_increasing"] = increasing(
            truth.values[:, 0], truth.values[:, 1:]
        )
        meas_t = sightings.values[:, 0].copy()
        origin = min(odo_t[0], truth_t[0])
    dropped = counts.get("odometry_time_not_increasing", 0) + counts.get(
        "groundtruth_time_not_increasing", 0
    )
    total = len(odometry.values) + len(truth.values)
    if dropped > max_dropped_fraction * total:
        odometry_back = counts.get("odometry_time_not_increasing", 0) > 0
        table = odometry if odometry_back else truth
        raise InputError(
            f"{name}: {dropped} of {total} odometry and ground-truth rows do not increase in time "
            f"(first at {table.path}:{table.lines[first_backward(table.values[:, 0])]}) "
            f"and would be dropped, more than max_dropped_fraction={max_dropped_fraction}"
            " (raise it to accept)"
        )
    odo_t, truth_t, meas_t = odo_t - origin, truth_t - origin, meas_t - origin
    # a row faster than any ground robot is a corrupted row, not motion: it would carry the
    # vehicle kilometres in one step (one row at 1e6 m/s read ATE 5 km)
    implausible = (np.abs(odo_values[:, 0]) > max_speed_m_s) | (
        np.abs(odo_values[:, 1]) > max_heading_rate_rad_s
    )
    if implausible.any():
        counts["odometry_implausible"] = int(implausible.sum())
        first = int(np.flatnonzero(implausible)[0])
        if implausible.sum() > max_dropped_fraction * len(odo_t):
            raise InputError(
                f"{odometry.path}: {int(implausible.sum())} of {len(odo_t)} rows move faster "
                f"than max_speed_m_s={max_speed_m_s:g} or turn faster than "
                f"max_heading_rate_rad_s={max_heading_rate_rad_s:g} (the first at "
                f"t={odo_t[first] + origin:.3f} s), more than max_dropped_fraction="
                f"{max_dropped_fraction}: columns swapped, or another kind of file?"
            )
        odo_t, odo_values = odo_t[~implausible], odo_values[~implausible]
    heading, repaired = repair_heading_glitches(truth_values[:, 2], truth_t, max_heading_rate_rad_s)
    dt = np.diff(odo_t)
    odometry_motion = Increments(
        odo_t[1:],
        dt,
        np.column_stack([odo_values[1:, 0] * dt, np.zeros(len(dt)), odo_values[1:, 1] * dt]),
    )
    try:
        quality = assess_truth(truth_t, truth_values[:, :2], heading, motion=odometry_motion)
    except InputError as error:
        raise InputError(f"{truth.path}: {error}") from None
    arrays = (odo_t, odo_values, truth_t, truth_values, heading, meas_t)
    for array in arrays:
        array.flags.writeable = False  # shared by every load of this recording
    return Recording(
        folder=folder,
        robot=robot,
        identity=identity,
        odometry=odometry,
        truth=truth,
        sightings=sightings,
        time_source=time_source,
        origin=float(origin),
        odo_t=odo_t,
        odo_values=odo_values,
        truth_t=truth_t,
        truth_xy=truth_values[:, :2],
        truth_heading=heading,
        truth_heading_raw=truth_values[:, 2],
        heading_samples_repaired=repaired,
        truth_quality=quality,
        meas_t=meas_t,
        counts=counts,
    )


def repair_heading_glitches(
    heading: np.ndarray, step_s: np.ndarray | float, max_rate_rad_s: float
) -> tuple[np.ndarray, int]:
    """Replace runs of headings that jump faster than ``max_rate_rad_s`` by the short-way
    interpolation between the good samples around them.

    A sample is good when its wrapped change from the last good sample is within
    ``max_rate_rad_s`` times the elapsed time. Samples between two good ones are then
    interpolated (wrapped, linear in index). A run longer than 50 samples is accepted as
    real motion (the last good sample is reset) so that the repair cannot run away.

    Args:
        heading: headings [rad], shape (N,).
        step_s: sample spacing [s] (scalar) or times (N,) [s].
        max_rate_rad_s: largest physical heading rate [rad/s].

    Returns:
        (repaired headings wrapped to [-pi, pi), number of samples replaced).
    """
    heading = np.asarray(heading, dtype=float)
    times = (
        np.arange(len(heading)) * step_s if np.isscalar(step_s) else np.asarray(step_s, dtype=float)
    )
    repaired = heading.copy()
    replaced = 0
    last_good = 0
    # the scan runs on Python floats (numpy scalars cost 0.5 s per UTIAS load); a good
    # sample keeps its own heading, so the last good value is heading[last_good]
    values, stamps = heading.tolist(), times.tolist()
    for i in range(1, len(values)):
        elapsed = stamps[i] - stamps[last_good]
        change = (values[i] - values[last_good] + math.pi) % (2.0 * math.pi) - math.pi
        if abs(change) <= max_rate_rad_s * max(elapsed, 1e-9) or i - last_good > 50:
            gap = i - last_good
            if gap > 1 and i - last_good <= 50:
                fractions = np.arange(1, gap) / gap
                repaired[last_good + 1 : i] = wrap_angle(repaired[last_good] + fractions * change)
                replaced += gap - 1
            last_good = i
    return np.asarray(wrap_angle(repaired)), replaced
