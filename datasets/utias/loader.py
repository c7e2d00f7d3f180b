"""``load_mrclam``: one robot of an MRCLAM folder as a ``Sequence`` (``datasets.utias``
says what the stream holds, what is repaired and what is fitted)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

from datasets.errors import InputError
from datasets.measurements import GyroSample, LandmarkScan, Measurement, Odometry, Sensor
from datasets.odometry_noise import mean_heading_density
from datasets.options import parse_options
from datasets.rotations import rot2_batch
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory
from datasets.truth_quality.intervals import TruthInterval, excluded_mask, merged_spans
from datasets.utias.calibration import calibrate, calibrated_odometry, reference_of
from datasets.utias.options import UtiasOptions
from datasets.utias.recording import read_recording, repair_heading_glitches
from datasets.utias.sightings import ROBOT_SUBJECTS, barcode_tables, build_scans


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


def load_mrclam(
    folder: Path, robot: int, config: UtiasOptions, name: str | None = None
) -> Sequence:
    """Build the ``Sequence`` of robot ``robot`` in the MRCLAM folder ``folder``."""
    name = name or f"utias:{folder}#robot{robot}"
    subject_of, surveyed = barcode_tables(folder)
    recording = read_recording(
        folder,
        robot,
        config.grid_step_s,
        config.max_dropped_fraction,
        config.max_heading_rate_rad_s,
        config.max_speed_m_s,
    )
    counts = dict(recording.counts)
    warnings: list[str] = []
    step = config.grid_step_s
    sightings = recording.sightings
    # the whole recording's sightings and Vicon: label swaps are detected on them (a short
    # run gets the same map as the full one)
    scored = reference_of(recording, config, subject_of, surveyed)
    bearings = np.abs(sightings.values[:, 3])
    # the camera's view: the widest bearing and longest range among the sightings
    field_of_view = float(np.rad2deg(2.0 * bearings.max())) if len(bearings) else None
    reach = float(sightings.values[:, 2].max()) if len(bearings) else None
    calibration = calibrate(scored, config, subject_of, surveyed, (field_of_view, reach))
    warnings.extend(calibration.warnings)
    scales = calibration.scales
    odometry_model = calibration.odometry_model
    odo_t, odo_values = recording.odo_t, calibrated_odometry(recording, scales)
    truth_t, truth_xy = recording.truth_t, recording.truth_xy
    truth_heading_raw = recording.truth_heading_raw
    recording_span = (float(odo_t[0]), float(odo_t[-1]))
    if config.duration_s is not None:
        keep = odo_t <= config.duration_s
        odo_t, odo_values = odo_t[keep], odo_values[keep]
        keep = truth_t <= config.duration_s
        truth_t, truth_xy = truth_t[keep], truth_xy[keep]
        truth_heading_raw = truth_heading_raw[keep]
    if len(odo_t) < 2 or len(truth_t) < 2:
        raise InputError(
            f"{recording.odometry.path}: fewer than two odometry or ground-truth rows in the "
            "selected time span"
        )

    scans, scan_ids, meas_counts = build_scans(
        sightings, recording.meas_t, recording_span, subject_of, config, end_s=float(odo_t[-1])
    )
    counts.update(meas_counts)
    # sightings outside the odometry's span cannot be used: trimming them changes nothing
    # in the run (an edge, not an error); going back in time inside it is a broken file
    outside = meas_counts["out_of_range_times"]
    if outside:
        origin = recording.origin
        warnings.append(
            f"{outside} of {len(sightings.values)} sightings lie outside the odometry's time "
            f"span ({recording_span[0] + origin:.3f}-{recording_span[1] + origin:.3f} s in "
            f"{sightings.path.name}) and were trimmed"
        )
    unknown = meas_counts["unknown_barcodes"]
    if unknown > config.max_dropped_fraction * len(sightings.values):
        raise InputError(
            f"{sightings.path}: {unknown} of {len(sightings.values)} sightings name barcodes "
            f"that {Path(folder) / 'Barcodes.dat'} does not list, more than "
            f"max_dropped_fraction={config.max_dropped_fraction}: the Barcodes.dat of another "
            "dataset?"
        )
    backwards = meas_counts["time_going_back"]
    if backwards > config.max_dropped_fraction * len(sightings.values):
        raise InputError(
            f"{sightings.path}: {backwards} of {len(sightings.values)} sightings go back in "
            f"time, more than max_dropped_fraction={config.max_dropped_fraction} "
            "(raise it to accept)"
        )
    gaps = np.diff(odo_t)
    long_gaps = [
        (float(odo_t[i]), float(gaps[i])) for i in np.flatnonzero(gaps > config.odometry_gap_s)
    ]

    heading, repaired = repair_heading_glitches(
        truth_heading_raw, truth_t, config.max_heading_rate_rad_s
    )
    counts["vicon_heading_samples_repaired"] = repaired
    # what the Vicon cannot vouch for, inside the selected span: scored nowhere
    end = float(truth_t[-1])
    excluded = tuple(
        replace(interval, end_s=min(interval.end_s, end))
        for interval in recording.truth_quality.intervals
        if interval.start_s <= end
    )
    excluded_s = float(np.sum(np.diff(merged_spans(excluded), axis=1))) if excluded else 0.0
    if excluded:
        counts["vicon_samples_excluded"] = int(excluded_mask(truth_t, excluded).sum())
        warnings.append(
            f"Vicon not trusted in {len(excluded)} interval(s), {excluded_s:.2f} s, excluded "
            "from the scoring (datasets.truth_quality): "
            + "; ".join(" ".join(interval.line().split()) for interval in excluded[:5])
            + ("; ..." if len(excluded) > 5 else "")
        )
    ground_truth = _ground_truth(
        truth_t, truth_xy, heading, subject_of, scored.location, scan_ids, excluded
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
        sighting_correlation=calibration.correlation,
        landmark_detection=calibration.detection,
        rate_hz={"odometry": 1.0 / step, "gyro": 1.0 / step},
    )
    start_velocity = ground_truth.history.block(BlockName.VELOCITY).values[0]
    initial_state = InitialState(
        t=float(truth_t[0]),
        position=truth_xy[0].copy(),
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

    time_source, origin = recording.time_source, recording.origin
    metadata = {
        "source": str(folder),
        "robot": robot,
        "time_source": time_source,
        "time_origin_s": float(origin),
        "measurement_time_uncertainty_s": 0.05
        if time_source == "row_grid" and odo_t[-1] + origin >= 1000
        else 0.0,
        "odometry_gaps": long_gaps,
        "swapped_labels": (
            "as in the file"
            if not config.fix_swapped_labels
            else ", ".join(f"barcode {a} <-> {b} survey positions" for a, b in scored.swaps)
            or "none detected"
        ),
        "excluded_truth": [interval.line() for interval in excluded],
        "options": config.model_dump(),
        "scans": len(scans),
        "odometry_noise": None if odometry_model is None else odometry_model.as_dict(),
        "odometry_scales": scales,
        "sighting_correlation": None
        if calibration.correlation is None
        else calibration.correlation.as_dict(),
        "detection_probability": None
        if calibration.detection is None
        else calibration.detection.as_dict(),
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
        reference_source="Vicon",
        warnings=tuple(warnings),
        counts={key: int(value) for key, value in counts.items()},
        excluded_truth_s=excluded_s,
        calibration=calibration.summary,
        landmark_ids=config.ids,
    )


def _with_ids(scan: LandmarkScan, visible: bool) -> LandmarkScan:
    return (
        scan
        if visible
        else LandmarkScan(t=scan.t, points=scan.points, covariances=scan.covariances, ids=None)
    )


def _ground_truth(
    t: np.ndarray,
    positions: np.ndarray,
    heading: np.ndarray,
    subject_of: dict[int, int],
    location: dict[int, np.ndarray],
    scan_ids: tuple[tuple[float, np.ndarray], ...],
    excluded: tuple[TruthInterval, ...] = (),
) -> GroundTruth:
    """Vicon poses, finite-difference velocities, the surveyed map (``location``: subject ->
    position, with the detected label swaps applied) keyed by barcode."""
    world_velocity = np.stack(
        [np.gradient(positions[:, 0], t), np.gradient(positions[:, 1], t)], axis=-1
    )
    body_velocity = np.einsum("nji,nj->ni", rot2_batch(heading), world_velocity)
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
        excluded=excluded,
    )
