"""UTIAS Multi-Robot Cooperative Localization and Mapping (MRCLAM) loader: ``utias:FOLDER#robotN``.

Real planar data (Leung et al., IJRR 2011): one robot's odometry (forward velocity, angular
velocity), monocular range/bearing sightings of barcoded landmarks, Vicon ground truth of
the robot and surveyed landmark positions. Any MRCLAM dataset folder works (files
``Barcodes.dat``, ``Landmark_Groundtruth.dat``, ``RobotN_{Odometry,Measurement,Groundtruth}.dat``).

What the stream contains (time-ordered; at equal times motion first, then the scan):
- the odometry rows are the commanded velocities, calibrated at load against the robot's
  Vicon (``datasets.odometry_calibration.fit_scales``; ``metadata['odometry_scales']``): a
  turn-rate factor (``odometry_turn_scale``), and a speed factor times
  ``max(0, 1 - coupling |omega|)`` (``odometry_speed_scale``,
  ``odometry_speed_turn_coupling``), all ``fit`` by default. Dataset 1 overstates the turn
  by 4-7 % on every robot, and the speed the more the robot turns (by 40 % at 0.3-0.6
  rad/s); then:
- ``GyroSample(t, rate=[omega])`` for every odometry row (the rate input of gyro-driven
  estimators such as ``sensor-based``);
- ``Odometry(t, velocity=[v, omega])`` for every odometry row; the sample at ``t`` is meant
  for the interval ending at ``t`` (the workbench's convention, as in dead reckoning);
  ``covariance`` is the per-sample white-noise covariance ``diag(sigma_v^2, sigma_omega^2)``
  (the integrated increment over ``dt`` then has covariance ``dt^2 * covariance``);
- ``LandmarkScan`` of the sightings sharing one time: body-frame points by
  ``datasets.range_bearing`` (the unbiased converted measurement and
  its covariance by default; ``landmark_conversion=first-order``: ``p = r (cos b, sin b)``
  with ``J diag(sr^2, sb^2) J^T``).

Quirks handled (all counted in ``Sequence.metadata['counts']``):
- *Rounded time column.* This copy is resampled on a 0.02 s grid but prints 5 significant
  digits, so after 1000 s the times are rounded to 0.1 s. When every printed odometry and
  ground-truth time is consistent with ``row index x grid_step_s`` within its printing
  resolution, the row index gives the time (``time_source='row_grid'``); measurement
  times are snapped to the grid and stay uncertain by +/-0.05 s after 1000 s. Otherwise
  (an original, irregular MRCLAM folder) the printed times are used, shifted to start at 0
  (``time_source='printed'``), and rows whose time does not increase are dropped.
- *Other robots' barcodes* (subjects 1-5, the MRCLAM robots) are not static landmarks:
  dropped. *Unknown barcodes* (not in ``Barcodes.dat``): dropped.
- *Stale repeats*: a sighting identical (range and bearing) to the previous sighting of the
  same barcode is a repeat of an old camera result: dropped (``drop_stale_repeats``).
- *Duplicate sightings*: the same barcode twice at one (snapped) time: the first is kept.
- *Out-of-range times*: sightings before the first or after the last odometry time: dropped.
- *Vicon heading glitches*: the resampling interpolated some headings the long way round
  across +/-pi (runs of 1-5 samples). ``repair_heading_glitches`` replaces every run whose
  implied rate exceeds ``max_heading_rate_rad_s`` by the short-way interpolation between
  the good samples around it; the number of repaired samples is in the metadata.
- *Swapped landmark labels*: in dataset 1 barcodes 18 and 61 (subjects 11 and 17) are
  swapped with respect to ``Landmark_Groundtruth.dat`` (the robots see barcode 18 where
  subject 17 is surveyed). The swap is detected from the data, not assumed
  (``detect_label_swaps``: a pair of barcodes whose sightings, placed with the Vicon poses,
  sit at each other's surveyed position), so another MRCLAM folder gets only the swaps its
  own data show; ``fix_swapped_labels=false`` keeps the file's labels. The metadata says
  which pairs were swapped.
- *Vicon position glitches*: a position that jumps away faster than
  ``max_vicon_speed_m_s`` is dropped from the truth (so no estimate is scored against it)
  until the track returns; counted (``vicon_position_glitch_samples``) and timed
  (``excluded_truth_s``).

Fitted at load against the robot's Vicon and the surveyed map, over the whole recording
(a short run gets the same as the full one), besides the odometry calibration above: the
odometry noise model (``odometry_noise``), the sightings' correlation in time
(``sighting_correlation``, ``datasets.sighting_correlation``) and the camera's detection
probability by range (``detection_probability``, ``datasets.detection_probability``); each
is stated in ``Sequence.noise`` and in the metadata, and each can be switched off.

Ground truth: Vicon poses (heading repaired), world and body velocity by central
differences of the Vicon positions (derived, not measured), the surveyed landmark map
(ids = barcodes) and the true barcode of every sighting (``scan_ids``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat, PositiveFloat

from datasets.detection_probability import DetectionProbability, fit_detection_probability
from datasets.errors import InputError
from datasets.measurements import GyroSample, LandmarkScan, Measurement, Odometry, Sensor
from datasets.odometry_calibration import speed_factors
from datasets.odometry_noise import OdometryNoiseModel, mean_heading_density, read_model_file
from datasets.options import parse_options
from datasets.range_bearing import convert
from datasets.rotations import rot2_batch, wrap_angle
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.sighting_correlation import (
    SightingCorrelation,
    fit_sighting_correlation,
    planar_residuals,
)
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.text_files import text_lines
from datasets.trajectory import Trajectory

ROBOT_SUBJECTS = frozenset({1, 2, 3, 4, 5})
"""MRCLAM subjects 1-5 are the robots; their barcodes are not static landmarks."""


class UtiasOptions(BaseModel):
    """``--data`` options of ``utias:FOLDER#robotN``."""

    model_config = ConfigDict(extra="forbid")
    ids: bool = Field(
        True,
        description="attach the barcodes to the scans (false: withheld, association by the estimator)",
    )
    landmark_conversion: Literal["unbiased", "first-order"] = Field(
        "unbiased",
        description="range/bearing sightings to body points: the unbiased converted measurement with "
        "its covariance (Mo et al. 1998, Duan et al. 2004) or the plain conversion with J diag J^T",
    )
    bearing_sigma_rad: float = Field(
        0.03, gt=0, description="bearing noise std [rad] (measured on this data: about 0.03)"
    )
    range_sigma_fraction: float = Field(
        0.05, ge=0, description="range noise std as a fraction of the range"
    )
    range_sigma_floor_m: float = Field(
        0.05, gt=0, description="lower bound of the range noise std [m]"
    )
    odometry_noise: str = Field(
        "fit",
        description="odometry noise model: 'fit' (variances growing with time, distance and turn, "
        "fitted at load against this robot's Vicon truth, datasets.odometry_noise), 'white' (the "
        "per-sample white noise below), or a YAML file from `workbench calibrate-noise`",
    )
    odometry_noise_window_s: float = Field(
        5.0, gt=0, description="'fit': window over which odometry is compared with the truth [s]"
    )
    odometry_sigma_v_m_s: float = Field(
        0.15,
        gt=0,
        description="odometry_noise=white: per-sample white-noise std of the forward velocity [m/s] (fits the 20 s drift vs Vicon of robot 1)",
    )
    odometry_sigma_omega_rad_s: float = Field(
        0.3,
        gt=0,
        description="odometry_noise=white: per-sample white-noise std of the angular velocity [rad/s] (fits the 1-20 s heading drift vs Vicon of robot 1)",
    )
    grid_step_s: float = Field(0.02, gt=0, description="row spacing of the resampled files [s]")
    drop_stale_repeats: bool = Field(
        True, description="drop a sighting identical to the previous one of the same barcode"
    )
    fix_swapped_labels: bool = Field(
        True,
        description="ground truth: swap the survey positions of barcodes whose sightings (placed "
        "with the Vicon poses) sit at each other's surveyed position (detected; dataset 1: 18 and 61)",
    )
    max_dropped_fraction: float = Field(
        0.01,
        ge=0,
        le=1,
        description="rows whose time does not increase are dropped and counted; more than this "
        "fraction of the odometry and ground truth is an error (the file is broken, not quirky)",
    )
    max_vicon_speed_m_s: float = Field(
        2.0,
        gt=0,
        description="Vicon positions jumping away faster than this are glitches, excluded from the scoring",
    )
    max_heading_rate_rad_s: float = Field(
        3.0, gt=0, description="Vicon heading changes faster than this are glitches"
    )
    duration_s: float | None = Field(
        None, gt=0, description="use only the first duration_s seconds"
    )
    odometry_gap_s: float = Field(
        0.5, gt=0, description="odometry gaps longer than this are listed in the metadata"
    )
    odometry_delay_s: float = Field(
        0.0,
        ge=0,
        description="calibration: shift the odometry (and gyro) later by this [s] (the commanded velocity leads the motion by about 0.16 s)",
    )
    sighting_correlation: Literal["fit", "none"] = Field(
        "fit",
        description="'fit': the errors of consecutive sightings of one landmark are correlated in "
        "time (range 0.9-0.98 within 0.5 s on dataset 1), fitted at load against this robot's "
        "Vicon and the surveyed map, and every estimator inflates a sighting's noise for the "
        "time since the previous one (datasets.sighting_correlation); 'none': independent "
        "sightings (the filters' pose NEES then reads 5-25 per 3 dof)",
    )
    odometry_speed_scale: PositiveFloat | Literal["fit"] = Field(
        "fit",
        description="calibration: multiply the forward velocity by this; 'fit': the factor that "
        "best matches this robot's Vicon over the whole recording (datasets.odometry_calibration"
        ".fit_scales); 1 keeps the commanded speed",
    )
    odometry_turn_scale: PositiveFloat | Literal["fit"] = Field(
        "fit",
        description="calibration: multiply the angular velocity by this; 'fit' as for the speed "
        "(the commanded turn rate overstates the turn by 4-7 percent on every dataset-1 robot); 1 "
        "keeps the commanded rate",
    )
    odometry_speed_turn_coupling: NonNegativeFloat | Literal["fit"] = Field(
        "fit",
        description="calibration [s/rad]: the forward velocity is further multiplied by "
        "max(0, 1 - coupling * |commanded turn rate|); 'fit' as for the speed (dataset 1: "
        "Vicon over commanded speed 1.02-1.03 driving straight, 0.59-0.62 at 0.3-0.6 rad/s, "
        "on every robot); 0 keeps the speed independent of the turn",
    )
    detection_probability: Literal["fit", "none"] = Field(
        "fit",
        description="'fit': how often the camera sights a barcode in its view, by range "
        "(datasets.detection_probability), fitted at load against this robot's Vicon and the "
        "surveyed map over the whole recording (dataset 1: 0.5-0.8 within 3 m, 0.15-0.25 "
        "beyond 5 m); ekf-slam-mht scores missed detections with it; 'none': not stated",
    )


@dataclass(frozen=True)
class _Table:
    """A parsed numeric file: values (n, k), the 1-based line number of every row and the
    number of decimals printed in its first column (the time's printing resolution)."""

    values: np.ndarray
    lines: np.ndarray
    path: Path
    first_decimals: np.ndarray


def read_table(path: Path, columns: tuple[str, ...]) -> _Table:
    """Read a whitespace-separated numeric file ('#' comments); ``InputError`` names file and line.

    Args:
        path: the file.
        columns: names of the expected columns (their count is enforced on every row).
    """
    rows: list[list[str]] = []
    lines: list[int] = []
    for number, line in text_lines(path, "MRCLAM file"):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        fields = text.split()
        if len(fields) != len(columns):
            raise InputError(
                f"{path}:{number}: expected {len(columns)} columns ({', '.join(columns)}), got {len(fields)}: '{text}'"
            )
        rows.append(fields)
        lines.append(number)
    if not rows:
        raise InputError(f"{path}: no data rows")
    # one conversion of the whole table (a per-row float() loop took 1.5 s per UTIAS load);
    # on failure, the row-by-row pass below finds the line to name
    try:
        values = np.array(rows, dtype=float)
    except ValueError:
        values = None
    if values is None or not np.isfinite(values).all():
        checked = []
        for fields, number in zip(rows, lines):
            try:
                row = [float(field) for field in fields]
            except ValueError:
                raise InputError(f"{path}:{number}: not a number in '{' '.join(fields)}'") from None
            if not np.all(np.isfinite(row)):
                raise InputError(f"{path}:{number}: non-finite value in '{' '.join(fields)}'")
            checked.append(row)
        values = np.array(checked)  # what Python reads and numpy did not (e.g. "1_0")
    decimals = [len(fields[0].lower().split("e")[0].partition(".")[2]) for fields in rows]
    return _Table(values, np.array(lines), path, np.array(decimals))


def printing_resolution(t: np.ndarray, significant_digits: int = 5) -> np.ndarray:
    """Resolution [s] of times printed with ``significant_digits`` (0.1 s for 1000-9999 s)."""
    magnitude = np.floor(np.log10(np.maximum(np.abs(t), 1e-12)))
    return 10.0 ** (magnitude - (significant_digits - 1))


def grid_times(
    printed: np.ndarray, step_s: float, decimals: np.ndarray | None = None
) -> np.ndarray | None:
    """Row-index times ``t0 + i * step_s`` when every printed time agrees within its printing
    resolution, else None.

    The resolution of a row is the finer of "5 significant digits" (this copy's format) and
    the decimals actually printed (so that long unix times with 3 decimals are judged at
    1 ms); the tolerance is half of it plus float slack.
    """
    grid = printed[0] + np.arange(len(printed)) * step_s
    resolution = printing_resolution(grid)
    if decimals is not None:
        resolution = np.minimum(resolution, 10.0 ** (-np.asarray(decimals, dtype=float)))
    tolerance = 0.5 * resolution + 1e-9
    return grid if np.all(np.abs(printed - grid) <= tolerance) else None


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


def parse_argument(argument: str | None) -> tuple[Path, int]:
    """``'FOLDER#robotN'`` -> (folder, N); ``InputError`` otherwise."""
    if not argument or "#" not in argument:
        raise InputError(
            f"utias: expected utias:FOLDER#robotN (e.g. utias:../shared/data/utias-mrclam1#robot1), got '{argument}'"
        )
    folder_text, _, robot_text = argument.rpartition("#")
    robot_text = robot_text.strip().lower()
    if not robot_text.startswith("robot") or not robot_text[5:].isdigit():
        raise InputError(f"utias: robot must be written robotN (e.g. robot1), got '{robot_text}'")
    folder = Path(folder_text).expanduser()
    if not folder.is_dir():
        raise InputError(f"utias: dataset folder '{folder}' does not exist")
    return folder, int(robot_text[5:])


def describe() -> list[str]:
    """Lines for ``workbench list --verbose``."""
    from datasets.options import describe_model

    return ["utias:FOLDER#robotN  any MRCLAM folder; --data options:"] + [
        "  " + line for line in describe_model(UtiasOptions)
    ]


def load(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """Load ``utias:FOLDER#robotN`` (``seed`` is unused: real data)."""
    config = parse_options(UtiasOptions, options, "utias --data")
    folder, robot = parse_argument(argument)
    return load_mrclam(folder, robot, config, name=f"utias:{argument}")


def _barcode_tables(folder: Path) -> tuple[dict[int, int], dict[int, np.ndarray]]:
    """(barcode -> subject, subject -> surveyed (x, y))."""
    barcodes = read_table(folder / "Barcodes.dat", ("subject", "barcode"))
    subject_of: dict[int, int] = {}
    for (subject, barcode), line in zip(barcodes.values, barcodes.lines):
        if int(barcode) in subject_of:
            raise InputError(f"{barcodes.path}:{line}: barcode {int(barcode)} listed twice")
        subject_of[int(barcode)] = int(subject)
    survey = read_table(
        folder / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std")
    )
    positions = {int(row[0]): row[1:3].copy() for row in survey.values}
    return subject_of, positions


def load_mrclam(
    folder: Path, robot: int, config: UtiasOptions, name: str | None = None
) -> Sequence:
    """Build the ``Sequence`` of robot ``robot`` in the MRCLAM folder ``folder``."""
    name = name or f"utias:{folder}#robot{robot}"
    counts: dict[str, int] = {}
    subject_of, surveyed = _barcode_tables(folder)
    odometry = read_table(folder / f"Robot{robot}_Odometry.dat", ("time", "v", "omega"))
    truth = read_table(folder / f"Robot{robot}_Groundtruth.dat", ("time", "x", "y", "heading"))
    sightings = read_table(
        folder / f"Robot{robot}_Measurement.dat", ("time", "barcode", "range", "bearing")
    )

    step = config.grid_step_s
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
        odo_t, odo_values, counts["odometry_time_not_increasing"] = _increasing(
            odometry.values[:, 0], odometry.values[:, 1:]
        )
        truth_t, truth_values, counts["groundtruth_time_not_increasing"] = _increasing(
            truth.values[:, 0], truth.values[:, 1:]
        )
        meas_t = sightings.values[:, 0].copy()
        origin = min(odo_t[0], truth_t[0])
    dropped = counts.get("odometry_time_not_increasing", 0) + counts.get(
        "groundtruth_time_not_increasing", 0
    )
    total = len(odometry.values) + len(truth.values)
    if dropped > config.max_dropped_fraction * total:
        raise InputError(
            f"{name}: {dropped} of {total} odometry and ground-truth rows do not increase in time "
            f"(first at {odometry.path}:{odometry.lines[_first_backward(odometry.values[:, 0])]}) "
            f"and would be dropped, more than max_dropped_fraction={config.max_dropped_fraction}"
            " (raise it to accept)"
        )
    odo_t, truth_t, meas_t = odo_t - origin, truth_t - origin, meas_t - origin
    # the whole recording's Vicon (headings repaired once): what the odometry is calibrated
    # against and the label swaps are detected with, so that a short run gets the same
    # calibration and map as the full one
    full_heading, _ = repair_heading_glitches(
        truth_values[:, 2], truth_t, config.max_heading_rate_rad_s
    )
    vicon = (truth_t, truth_values[:, :2], full_heading)
    # scales first, then the noise model of the scaled odometry (fit_scales says why)
    scales = _odometry_scales(config, odo_t, odo_values, vicon, name)
    odo_values = np.column_stack(
        [
            odo_values[:, 0] * speed_factors(odo_values[:, 1], scales["speed"], scales["coupling"]),
            odo_values[:, 1] * scales["turn"],
        ]
    )
    odometry_model = _odometry_noise_model(config, odo_t, odo_values, vicon, name)
    # the whole recording's sightings: label swaps and the sighting correlation are judged
    # on all of them, as the odometry is calibrated
    every_scan, _, _ = _build_scans(
        sightings, meas_t, (float(odo_t[0]), float(odo_t[-1])), subject_of, config
    )
    swaps: list[tuple[int, int]] = []
    if config.fix_swapped_labels:
        swaps = detect_label_swaps(every_scan, *vicon, subject_of, surveyed)
    location = _swapped_survey(surveyed, subject_of, swaps)
    correlation = _sighting_correlation(config, every_scan, vicon, location, subject_of, name)
    bearings = np.abs(sightings.values[:, 3])
    # the camera's view: the widest bearing and longest range among the sightings
    field_of_view = float(np.rad2deg(2.0 * bearings.max())) if len(bearings) else None
    reach = float(sightings.values[:, 2].max()) if len(bearings) else None
    detection = _detection_probability(
        config,
        every_scan,
        vicon,
        location,
        subject_of,
        (field_of_view, reach),
        name,
    )
    recording_span = (float(odo_t[0]), float(odo_t[-1]))
    if config.duration_s is not None:
        keep = odo_t <= config.duration_s
        odo_t, odo_values = odo_t[keep], odo_values[keep]
        keep = truth_t <= config.duration_s
        truth_t, truth_values = truth_t[keep], truth_values[keep]
    if len(odo_t) < 2 or len(truth_t) < 2:
        raise InputError(
            f"{odometry.path}: fewer than two odometry or ground-truth rows in the selected time span"
        )

    scans, scan_ids, meas_counts = _build_scans(
        sightings, meas_t, recording_span, subject_of, config, end_s=float(odo_t[-1])
    )
    counts.update(meas_counts)
    misplaced = meas_counts["out_of_range_times"] + meas_counts["time_going_back"]
    if misplaced > config.max_dropped_fraction * len(sightings.values):
        raise InputError(
            f"{sightings.path}: {misplaced} of {len(sightings.values)} sightings lie outside the "
            f"odometry's time span ({recording_span[0] + origin:.3f}-{recording_span[1] + origin:.3f} s)"
            " or go back in time, more than max_dropped_fraction="
            f"{config.max_dropped_fraction} (raise it to accept)"
        )
    gaps = np.diff(odo_t)
    long_gaps = [
        (float(odo_t[i]), float(gaps[i])) for i in np.flatnonzero(gaps > config.odometry_gap_s)
    ]

    heading, repaired = repair_heading_glitches(
        truth_values[:, 2], truth_t, config.max_heading_rate_rad_s
    )
    counts["vicon_heading_samples_repaired"] = repaired
    glitches = vicon_position_glitches(truth_t, truth_values[:, :2], config.max_vicon_speed_m_s)
    counts["vicon_position_glitch_samples"] = int(glitches.sum())
    good = ~glitches  # glitch samples leave the truth: no estimate pairs with them
    ground_truth = _ground_truth(
        truth_t[good], truth_values[good, :2], heading[good], subject_of, surveyed, swaps, scan_ids
    )

    speeds = odo_values[:, 0]
    if odometry_model is None:
        gyro_density = config.odometry_sigma_omega_rad_s * np.sqrt(step)
    else:
        gyro_density = mean_heading_density(
            odometry_model,
            np.column_stack([speeds * step, np.zeros(len(speeds)), odo_values[:, 1] * step]),
            np.full(len(speeds), step),
        )
    noise = NoiseSpec(
        gyro_noise_density=gyro_density,
        odometry=odometry_model,
        landmark_field_of_view_deg=field_of_view,
        landmark_range_m=reach,
        sighting_correlation=correlation,
        landmark_detection=detection,
        rate_hz={"odometry": 1.0 / step, "gyro": 1.0 / step},
    )
    start_velocity = ground_truth.history.block(BlockName.VELOCITY).values[0]
    initial_state = InitialState(
        t=float(truth_t[0]),
        position=truth_values[0, :2].copy(),
        rotation=np.array(heading[0]),
        velocity=start_velocity.copy(),
        position_sigma_m=1e-3,
        rotation_sigma_rad=1e-3,
        velocity_sigma_m_s=0.05,
    )
    white_cov = np.diag([config.odometry_sigma_v_m_s**2, config.odometry_sigma_omega_rad_s**2])
    ids_visible = config.ids

    def stream() -> Iterator[Measurement]:
        scan_index = 0
        previous_t: float | None = None
        for t, speed, rate in zip(odo_t + config.odometry_delay_s, speeds, odo_values[:, 1]):
            while scan_index < len(scans) and scans[scan_index].t < t:
                yield _with_ids(scans[scan_index], ids_visible)
                scan_index += 1
            dt = step if previous_t is None else max(float(t) - previous_t, 1e-9)
            previous_t = float(t)
            covariance = (
                white_cov
                if odometry_model is None
                else odometry_model.velocity_covariance(speed, rate, dt)
            )
            yield GyroSample(t=float(t), rate=np.array([rate]))
            yield Odometry(t=float(t), covariance=covariance, velocity=np.array([speed, rate]))
            while scan_index < len(scans) and scans[scan_index].t <= t:
                yield _with_ids(scans[scan_index], ids_visible)
                scan_index += 1

    metadata = {
        "source": str(folder),
        "reference_source": "Vicon",
        "robot": robot,
        "time_source": time_source,
        "time_origin_s": float(origin),
        "measurement_time_uncertainty_s": 0.05
        if time_source == "row_grid" and odo_t[-1] + origin >= 1000
        else 0.0,
        "counts": {key: int(value) for key, value in counts.items()},
        "odometry_gaps": long_gaps,
        "swapped_labels": (
            "as in the file"
            if not config.fix_swapped_labels
            else ", ".join(f"barcode {a} <-> {b} survey positions" for a, b in swaps)
            or "none detected"
        ),
        "excluded_truth_s": float(np.sum(np.diff(truth_t)[glitches[1:]]))
        if len(truth_t) > 1
        else 0.0,
        "options": config.model_dump(),
        "scans": len(scans),
        "odometry_noise": None if odometry_model is None else odometry_model.as_dict(),
        "odometry_scales": scales,
        "sighting_correlation": None if correlation is None else correlation.as_dict(),
        "detection_probability": None if detection is None else detection.as_dict(),
    }
    return Sequence(
        name=name,
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.GYRO, Sensor.LANDMARKS}),
        stream=stream,
        ground_truth=ground_truth,
        noise=noise,
        initial_state=initial_state,
        metadata=metadata,
    )


def _increments(config: UtiasOptions, odo_t: np.ndarray, odo_values: np.ndarray):
    """The odometry rows (time, speed, turn rate) as ``odometry_calibration.Increments``."""
    from datasets.odometry_calibration import Increments

    dt = np.diff(odo_t)
    return Increments(
        odo_t[1:] + config.odometry_delay_s,
        dt,
        np.column_stack([odo_values[1:, 0] * dt, np.zeros(len(dt)), odo_values[1:, 1] * dt]),
    )


def _against_vicon(
    fit,
    config: UtiasOptions,
    odo_t: np.ndarray,
    odo_values: np.ndarray,
    vicon: tuple,
    what: str,
    remedy: str,
):
    """``fit(increments, truth_t, positions, headings, window_s, tolerance_s=...)`` of the
    odometry rows (times, (speed, turn rate)) against the robot's Vicon ``vicon`` = (times,
    positions (m, 2), repaired headings), each odometry end paired with the nearest truth
    sample (grid data share the times, printed logs have two clocks), on windows of
    ``odometry_noise_window_s``. An ``InputError`` names ``what`` failed and the ``remedy``."""
    truth_t, positions, heading = vicon
    try:
        return fit(
            _increments(config, odo_t, odo_values),
            truth_t,
            positions,
            heading,
            config.odometry_noise_window_s,
            tolerance_s=0.5 * float(np.median(np.diff(truth_t))) + 1e-9,
        )
    except InputError as error:
        raise InputError(f"{what}: {error} ({remedy})") from None


def _odometry_scales(
    config: UtiasOptions, odo_t: np.ndarray, odo_values: np.ndarray, vicon: tuple, name: str
) -> dict:
    """The calibration of the commanded velocities (``odometry_calibration.fit_scales``):
    the speed and turn-rate factors and the speed-turn coupling, as given, or ``fit``
    against this robot's own Vicon over the whole recording (before ``duration_s`` trims
    it, as the noise model), on windows of ``odometry_noise_window_s``, with the given ones
    held. For the metadata: the three values, where they came from and the heading and
    position RMS on the windows before and after."""
    wanted = {
        "speed": config.odometry_speed_scale,
        "turn": config.odometry_turn_scale,
        "coupling": config.odometry_speed_turn_coupling,
    }
    given = {key: float(value) for key, value in wanted.items() if value != "fit"}
    if len(given) == len(wanted):
        return {**given, "source": "given"}
    from datasets.odometry_calibration import fit_scales

    result = _against_vicon(
        partial(fit_scales, fixed=given),
        config,
        odo_t,
        odo_values,
        vicon,
        f"{name}: odometry calibration = fit ({', '.join(sorted(set(wanted) - set(given)))})",
        "give the factors, e.g. --data odometry_turn_scale=1",
    )
    held = "".join(f"; {key} given as {value:g}" for key, value in given.items())
    return {
        "speed": result.speed,
        "turn": result.turn,
        "coupling": result.coupling,
        "source": (
            f"fitted at load against {name}'s Vicon truth ({result.windows} windows of "
            f"{config.odometry_noise_window_s:g} s): speed {result.speed:.4f}, turn "
            f"{result.turn:.4f}, speed-turn coupling {result.coupling:.3f} s/rad{held}"
        ),
        "heading_rms_before_deg": float(np.rad2deg(result.heading_rms_before_rad)),
        "heading_rms_after_deg": float(np.rad2deg(result.heading_rms_after_rad)),
        "position_rms_before_m": result.position_rms_before_m,
        "position_rms_after_m": result.position_rms_after_m,
    }


def _odometry_noise_model(
    config: UtiasOptions, odo_t: np.ndarray, odo_values: np.ndarray, vicon: tuple, name: str
) -> OdometryNoiseModel | None:
    """The odometry noise model ``config.odometry_noise`` asks for: ``fit`` against this
    robot's own Vicon truth over the whole recording (``datasets.odometry_calibration``,
    windows of ``odometry_noise_window_s``; before ``duration_s`` trims it, so that a short
    run gets the same model as the full one), ``white`` (None: the per-sample white noise
    of ``odometry_sigma_v_m_s``, ``odometry_sigma_omega_rad_s``), or a YAML file written by
    ``workbench calibrate-noise``."""
    choice = config.odometry_noise
    if choice == "white":
        return None
    if choice != "fit":
        return read_model_file(Path(choice))
    from datasets.odometry_calibration import build_windows, fit_odometry_noise

    windows = _against_vicon(
        build_windows,
        config,
        odo_t,
        odo_values,
        vicon,
        f"{name}: odometry_noise=fit",
        "use --data odometry_noise=white, or a model file from `workbench calibrate-noise`",
    )
    fit = fit_odometry_noise(windows, "")
    source = (
        f"fitted at load against {name}'s Vicon truth ({fit.windows} windows of "
        f"{config.odometry_noise_window_s:g} s; {len(fit.excluded)} outlier windows excluded)"
    )
    return OdometryNoiseModel(fit.model.rates, source)


def _with_ids(scan: LandmarkScan, visible: bool) -> LandmarkScan:
    return (
        scan
        if visible
        else LandmarkScan(t=scan.t, points=scan.points, covariances=scan.covariances, ids=None)
    )


def _first_backward(t: np.ndarray) -> int:
    """Index of the first time not after its predecessor (0 when there is none)."""
    backward = np.flatnonzero(np.diff(t) <= 0)
    return int(backward[0] + 1) if backward.size else 0


def _increasing(t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Keep rows whose time increases strictly over every earlier kept row."""
    keep = np.zeros(len(t), dtype=bool)
    latest = -np.inf
    for i, time in enumerate(t):
        if time > latest:
            keep[i] = True
            latest = time
    return t[keep], values[keep], int((~keep).sum())


def _build_scans(
    sightings: _Table,
    meas_t: np.ndarray,
    span: tuple[float, float],
    subject_of: dict[int, int],
    config: UtiasOptions,
    end_s: float | None = None,
) -> tuple[list[LandmarkScan], tuple[tuple[float, np.ndarray], ...], dict[str, int]]:
    """Group sightings into scans (one per time), dropping what is not a landmark sighting.
    ``span``: the recording's odometry time span (a sighting outside it is dropped and
    counted); ``end_s``: the selected end (``duration_s``: later sightings are not selected,
    which is not a drop)."""
    counts = dict.fromkeys(
        (
            "robot_barcodes",
            "unknown_barcodes",
            "stale_repeats",
            "duplicate_sightings",
            "out_of_range_times",
            "time_going_back",
            "nonpositive_range",
        ),
        0,
    )
    last_seen: dict[int, tuple[float, float]] = {}
    groups: dict[float, dict[int, tuple[float, float]]] = {}
    order: list[float] = []
    latest = -np.inf
    for row, t in zip(sightings.values, meas_t):
        barcode, rng, bearing = int(row[1]), float(row[2]), float(row[3])
        if t < span[0] - 1e-9 or t > span[1] + 1e-9:
            counts["out_of_range_times"] += 1
            continue
        if end_s is not None and t > end_s + 1e-9:
            continue
        if t < latest - 1e-9:
            counts["time_going_back"] += 1
            continue
        latest = max(latest, t)
        subject = subject_of.get(barcode)
        if subject is None:
            counts["unknown_barcodes"] += 1
            continue
        if subject in ROBOT_SUBJECTS:
            counts["robot_barcodes"] += 1
            continue
        if rng <= 0.0:
            counts["nonpositive_range"] += 1
            continue
        if config.drop_stale_repeats and last_seen.get(barcode) == (rng, bearing):
            counts["stale_repeats"] += 1
            continue
        last_seen[barcode] = (rng, bearing)
        key = round(float(t), 9)
        if key not in groups:
            groups[key] = {}
            order.append(key)
        if barcode in groups[key]:
            counts["duplicate_sightings"] += 1
            continue
        groups[key][barcode] = (rng, bearing)
    scans: list[LandmarkScan] = []
    scan_ids: list[tuple[float, np.ndarray]] = []
    for key in order:
        group = groups[key]
        ids = np.array(sorted(group), dtype=int)
        ranges = np.array([group[i][0] for i in ids])
        bearings = np.array([group[i][1] for i in ids])
        sigma_r = np.maximum(config.range_sigma_floor_m, config.range_sigma_fraction * ranges)
        points, covariances = convert(
            ranges, bearings, sigma_r, config.bearing_sigma_rad, config.landmark_conversion
        )
        scans.append(LandmarkScan(t=key, points=points, covariances=covariances, ids=ids))
        scan_ids.append((key, ids))
    return scans, tuple(scan_ids), counts


def detect_label_swaps(
    scans: list[LandmarkScan],
    truth_t: np.ndarray,
    truth_xy: np.ndarray,
    heading: np.ndarray,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
    min_sightings: int = 20,
    tolerance_m: float = 0.5,
) -> list[tuple[int, int]]:
    """Pairs of barcodes whose sightings, placed in the world with the Vicon poses, sit at
    each other's surveyed position (median within ``tolerance_m``) and more than
    ``tolerance_m`` from their own: labels swapped in the survey (MRCLAM dataset 1: 18 and
    61). Barcodes with fewer than ``min_sightings`` sightings are not judged."""
    placed: dict[int, list[np.ndarray]] = {}
    for scan in scans:
        i = min(int(np.searchsorted(truth_t, scan.t)), len(truth_t) - 1)
        rotation = rot2_batch(np.array([heading[i]]))[0]
        for barcode, point in zip(scan.ids, scan.points):
            placed.setdefault(int(barcode), []).append(truth_xy[i] + rotation @ point)
    seen = {
        barcode: np.median(np.array(points), axis=0)
        for barcode, points in placed.items()
        if len(points) >= min_sightings and subject_of.get(barcode) in surveyed
    }
    survey = {barcode: surveyed[subject_of[barcode]] for barcode in seen}
    misplaced = sorted(b for b in seen if np.linalg.norm(seen[b] - survey[b]) > tolerance_m)
    swaps = []
    for index, first in enumerate(misplaced):
        for second in misplaced[index + 1 :]:
            if (
                np.linalg.norm(seen[first] - survey[second]) < tolerance_m
                and np.linalg.norm(seen[second] - survey[first]) < tolerance_m
            ):
                swaps.append((first, second))
    return swaps


def _swapped_survey(
    surveyed: dict[int, np.ndarray], subject_of: dict[int, int], swaps: list[tuple[int, int]]
) -> dict[int, np.ndarray]:
    """Surveyed positions by subject with the detected barcode ``swaps`` applied."""
    location = dict(surveyed)
    for first, second in swaps:
        a, b = subject_of[first], subject_of[second]
        location[a], location[b] = surveyed[b], surveyed[a]
    return location


def _sighting_correlation(
    config: UtiasOptions,
    scans: list[LandmarkScan],
    vicon: tuple,
    location: dict[int, np.ndarray],
    subject_of: dict[int, int],
    name: str,
) -> SightingCorrelation | None:
    """The time correlation of the sightings' errors (``datasets.sighting_correlation``):
    ``fit`` against this robot's Vicon poses (interpolated to each sighting) and the surveyed
    map over the whole recording, or none (``sighting_correlation=none``)."""
    if config.sighting_correlation == "none":
        return None
    truth_t, truth_xy, heading = vicon
    times = np.concatenate([np.full(len(scan.ids), scan.t) for scan in scans] or [np.zeros(0)])
    barcodes = np.concatenate([np.asarray(scan.ids, int) for scan in scans] or [np.zeros(0, int)])
    points = np.concatenate([scan.points for scan in scans] or [np.zeros((0, 2))])
    surveyed = {b: location.get(subject_of.get(int(b), -1)) for b in set(barcodes.tolist())}
    known = np.array([surveyed[int(b)] is not None for b in barcodes], dtype=bool)
    times, barcodes, points = times[known], barcodes[known], points[known]
    landmarks = np.array([surveyed[int(b)] for b in barcodes]).reshape(-1, 2)
    position = np.column_stack([np.interp(times, truth_t, truth_xy[:, k]) for k in (0, 1)])
    rotation = rot2_batch(np.interp(times, truth_t, np.unwrap(heading)))
    predicted = np.einsum("nji,nj->ni", rotation, landmarks - position)  # R^T (l - p)
    try:
        return fit_sighting_correlation(
            times,
            barcodes,
            planar_residuals(points, predicted),
            f"fitted at load against {name}'s Vicon poses and the surveyed map "
            f"({len(times)} sightings)",
        )
    except InputError as error:
        raise InputError(
            f"{name}: sighting_correlation=fit: {error} (use --data sighting_correlation=none)"
        ) from None


def _detection_probability(
    config: UtiasOptions,
    scans: list[LandmarkScan],
    vicon: tuple,
    location: dict[int, np.ndarray],
    subject_of: dict[int, int],
    view: tuple[float | None, float | None],
    name: str,
) -> DetectionProbability | None:
    """How often the camera sights a barcode in its ``view`` (field of view [deg], range
    [m]), by range (``datasets.detection_probability``): ``fit`` against this robot's Vicon
    poses and the surveyed map (label swaps applied) over the whole recording, or none."""
    if config.detection_probability == "none" or not scans:
        return None  # nothing to fit from: a recording without sightings states none
    barcode_of = {subject: barcode for barcode, subject in subject_of.items()}
    landmarks = {
        int(barcode_of[subject]): np.asarray(position, float)
        for subject, position in location.items()
        if subject in barcode_of and subject not in ROBOT_SUBJECTS
    }
    return fit_detection_probability(
        [(scan.t, np.asarray(scan.ids, int)) for scan in scans],
        vicon,
        landmarks,
        *view,
        f"fitted at load against {name}'s Vicon poses and the surveyed map ({len(scans)} scans)",
    )


def vicon_position_glitches(t: np.ndarray, xy: np.ndarray, max_speed_m_s: float) -> np.ndarray:
    """(N,) bool: Vicon samples whose position jumps away from the last good sample faster
    than ``max_speed_m_s`` (a lost or swapped marker: metres in a few samples), until the
    track comes back within reach of that sample. Excluded from the scoring."""
    bad = np.zeros(len(t), bool)
    last = 0
    stamps, x, y = t.tolist(), xy[:, 0].tolist(), xy[:, 1].tolist()  # Python floats: fast
    for i in range(1, len(stamps)):
        reach = max_speed_m_s * max(stamps[i] - stamps[last], 1e-9)
        if math.hypot(x[i] - x[last], y[i] - y[last]) > reach + 0.05:  # 5 cm: Vicon jitter
            bad[i] = True
        else:
            last = i
    return bad


def _ground_truth(
    t: np.ndarray,
    positions: np.ndarray,
    heading: np.ndarray,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
    swaps: list[tuple[int, int]],
    scan_ids: tuple[tuple[float, np.ndarray], ...],
) -> GroundTruth:
    """Vicon poses, finite-difference velocities, surveyed map keyed by barcode with the
    detected label ``swaps`` applied."""
    world_velocity = np.stack(
        [np.gradient(positions[:, 0], t), np.gradient(positions[:, 1], t)], axis=-1
    )
    body_velocity = np.einsum("nji,nj->ni", rot2_batch(heading), world_velocity)
    location = _swapped_survey(surveyed, subject_of, swaps)
    barcode_of = {subject: barcode for barcode, subject in subject_of.items()}
    ids = np.array(
        sorted(barcode_of[s] for s in location if s in barcode_of and s not in ROBOT_SUBJECTS),
        dtype=int,
    )
    subject_by_barcode = {barcode_of[s]: s for s in location if s in barcode_of}
    landmark_positions = np.array([location[subject_by_barcode[i]] for i in ids]).reshape(-1, 2)
    pose = Trajectory(t=t.copy(), positions=positions.copy(), rotations=heading.copy())
    history = StateHistory(
        pose=pose,
        blocks={BlockName.VELOCITY: StateBlock(t.copy(), world_velocity, None, Frame.WORLD)},
    )
    return GroundTruth(
        history=history,
        landmarks=LandmarkMap(ids=ids, positions=landmark_positions, frame=Frame.WORLD),
        body_velocity=StateBlock(t.copy(), body_velocity, None, Frame.BODY),
        scan_ids=scan_ids,
    )
