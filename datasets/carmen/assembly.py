"""``carmen_sequence``: a parsed CARMEN log as a ``Sequence`` (``datasets.carmen`` says what
the stream holds and what the loader decides)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from datasets.carmen.log_parsing import ParsedLog
from datasets.carmen.messages import LaserMessage
from datasets.carmen.noise import odometry_model
from datasets.carmen.odometry import (
    find_stale_runs,
    interpolate_poses,
    relative_increments,
    spread_stale,
    stale_line,
)
from datasets.carmen.options import CarmenOptions
from datasets.carmen.stamps import StampRepair, repair_line, repair_order
from datasets.errors import InputError
from datasets.laser2d.frontend import Laser2dFrontEnd
from datasets.laser2d.scan import PlanarScan
from datasets.measurements import Measurement, Odometry, Sensor
from datasets.odometry_noise import OdometryNoiseModel, mean_heading_density
from datasets.pass_report import PassReport
from datasets.sequence import InitialState, NoiseSpec, Sequence


def increment_covariances(
    model: OdometryNoiseModel, increments: np.ndarray, durations: np.ndarray
) -> np.ndarray:
    """``model.increment_covariance`` of every increment (n, 3) over ``durations`` (n,) [s], at
    once: (n, 3, 3)."""
    variances = model.variances(
        durations, np.hypot(increments[:, 0], increments[:, 1]), increments[:, 2]
    )
    covariances = np.zeros((len(increments), 3, 3))
    covariances[:, [0, 1, 2], [0, 1, 2]] = variances
    return covariances


def _repaired(kind: str, messages: list, warnings: list[str]) -> StampRepair:
    """The stamp repair of one message type, its line added to ``warnings`` when it changed
    anything."""
    stamps = [message.stamp for message in messages]
    contents = [
        (message.ranges.tobytes(), message.odometry.tobytes())
        if isinstance(message, LaserMessage)
        else message.pose.tobytes()
        for message in messages
    ]
    repair = repair_order(stamps, contents)
    if repair.changed:
        lines = np.array([message.line for message in messages])
        warnings.append(repair_line(kind, repair, lines, stamps))
    return repair


def laser_mounting(
    log: ParsedLog, scans: list[LaserMessage], options: CarmenOptions, warnings: list[str]
) -> tuple[np.ndarray, str]:
    """The laser's pose in the robot frame (3,) (x [m], y [m], theta [rad]) and where it came
    from: the option, the ``PARAM`` lines (``robot_frontlaser_offset``,
    ``_side_offset``, ``_angular_offset``; ``rearlaser`` for the rear one, which faces back),
    a ``ROBOTLASER1`` line's own, else zero (a line added to ``warnings``)."""
    which = "frontlaser" if options.laser == "front" else "rearlaser"
    facing = 0.0 if options.laser == "front" else np.pi
    if options.laser_offset_m is not None:
        return np.array([options.laser_offset_m, 0.0, facing]), "laser_offset_m option"
    parameter = log.parameters.get(f"robot_{which}_offset")
    if parameter is not None:
        values = []
        for suffix in ("offset", "side_offset", "angular_offset"):
            entry = log.parameters.get(f"robot_{which}_{suffix}")
            try:
                values.append(float(entry.value) if entry is not None else 0.0)
            except ValueError:
                raise InputError(
                    f"{log.path}:{entry.line}: PARAM {entry.name} is '{entry.value}', not a number"
                ) from None
        return (
            np.array([values[0], values[1], values[2] + facing]),
            f"PARAM robot_{which}_offset {parameter.value} (line {parameter.line})",
        )
    stated = [scan.mounting for scan in scans if scan.mounting is not None]
    if stated:
        return np.median(np.array(stated), axis=0), "ROBOTLASER1 laser pose in the robot pose"
    warnings.append(
        f"laser offset: the log has no PARAM robot_{which}_offset: taken as 0 (the laser at "
        "the robot's origin; --data laser_offset_m=X states it)"
    )
    return np.array([0.0, 0.0, facing]), "none in the log: 0"


def _odometry_evidence(
    log: ParsedLog, times: np.ndarray, poses: np.ndarray, warnings: list[str]
) -> tuple[np.ndarray | None, np.ndarray | None, str, StampRepair | None]:
    """The ODOM lines (repaired) as (times, poses) or None, one line comparing them with the
    scans' own odometry, and their stamp repair (None without ODOM lines)."""
    if not log.odometry:
        return None, None, "the log has no ODOM lines", None
    repair = _repaired("ODOM lines", log.odometry, warnings)
    odo_t = repair.times
    odo_pose = np.array([log.odometry[i].pose for i in repair.kept])
    if len(odo_t) < 2:
        return None, None, f"{len(odo_t)} ODOM line(s): too few to interpolate", repair
    latest = np.clip(np.searchsorted(odo_t, times, side="right") - 1, 0, len(odo_t) - 1)
    same = int(np.count_nonzero(np.all(odo_pose[latest] == poses, axis=1)))
    gap = np.hypot(*(interpolate_poses(times, odo_t, odo_pose)[:, :2] - poses[:, :2]).T)
    return (
        odo_t,
        odo_pose,
        f"{len(odo_t)} ODOM lines: a scan's own odometry equals the latest ODOM pose before it "
        f"at {same} of {len(times)} scans and lies a median {1e3 * np.median(gap):.1f} mm "
        f"(95th percentile {1e3 * np.percentile(gap, 95):.1f} mm) from the ODOM poses "
        "interpolated to its stamp",
        repair,
    )


def carmen_sequence(log: ParsedLog, options: CarmenOptions, name: str) -> Sequence:
    """The ``Sequence`` of a parsed log (``datasets.carmen``)."""
    return carmen_source(log, options, name)[0]


def carmen_source(
    log: ParsedLog, options: CarmenOptions, name: str
) -> tuple[Sequence, Laser2dFrontEnd]:
    """The ``Sequence`` of a parsed log and its front end (whose ``log`` holds the
    re-observation pairs once the stream has run: ``benchmarks/bench_carmen.py
    --calibrate`` fits the corner scale on them)."""
    path = Path(log.path)
    warnings: list[str] = []
    front = options.laser == "front"
    chosen = [message for message in log.lasers if message.front == front]
    other = len(log.lasers) - len(chosen)
    if len(chosen) < 2:
        raise InputError(
            f"{path}: {len(chosen)} {options.laser} laser line(s): need at least 2 scans "
            f"(--data laser={'rear' if front else 'front'}?)"
        )
    kinds = sorted({message.kind for message in chosen})
    repair = _repaired(" and ".join(kinds) + " scans", chosen, warnings)
    scans = [chosen[i] for i in repair.kept]
    times = repair.times
    own_poses = np.array([scan.odometry for scan in scans])
    odo_t, odo_pose, evidence, odo_repair = _odometry_evidence(log, times, own_poses, warnings)
    if options.odometry == "messages":
        if odo_t is None:
            raise InputError(f"{path}: --data odometry=messages, but {evidence}")
        poses = interpolate_poses(times, odo_t, odo_pose)
        source = "ODOM lines interpolated to the scan stamps (odometry=messages)"
    else:
        poses = own_poses
        source = "the scans' own odom fields (odometry=scan)"
    warnings.append(f"odometry: {source}; {evidence}")
    lines = np.array([scan.line for scan in scans])
    stale = find_stale_runs(times, poses)
    if stale.runs:
        warnings.append(stale_line(stale, times, lines, len(times)))
        if options.stale_odometry == "spread":
            poses = spread_stale(times, poses, stale)
    skipped = dict(log.skipped)
    if other:
        skipped["other laser"] = other
    if skipped:
        warnings.append(
            "skipped: "
            + ", ".join(f"{count} {kind} line(s)" for kind, count in sorted(skipped.items()))
        )

    keep = np.arange(0, len(scans), options.scan_stride)
    if options.max_scans is not None:
        keep = keep[: options.max_scans]
    if len(keep) < 2:
        raise InputError(f"{path}: {len(keep)} scan(s) left after scan_stride/max_scans")
    scans = [scans[i] for i in keep]
    times, poses = times[keep], poses[keep]
    increments = relative_increments(poses)
    durations = np.diff(times)
    model = odometry_model(options.odometry_noise)
    covariances = increment_covariances(model, increments, durations)
    mounting, mounting_source = laser_mounting(log, scans, options, warnings)
    planar = [
        PlanarScan(
            t=float(t),
            ranges=scan.ranges,
            angles=scan.angles(),
            min_range_m=options.corner.min_range_m,
            max_range_m=min(scan.max_range_m, options.corner.max_range_m),
            mounting=mounting,
        )
        for t, scan in zip(times, scans)
    ]
    front_end = Laser2dFrontEnd(options)
    # the front end's corner figures, filled once the stream has run
    pass_report = PassReport.expecting("corners")

    def stream() -> Iterator[Measurement]:
        for index, scan in enumerate(planar):
            if index == 0:
                result = front_end.frame(0, scan)
            else:
                increment, covariance = increments[index - 1], covariances[index - 1]
                result = front_end.frame(index, scan, increment, covariance)
                yield Odometry(
                    t=scan.t,
                    covariance=covariance,
                    relative_pose=increment.copy(),
                    dt=float(durations[index - 1]),
                    frame=True,  # a laser scan: the data expect a pose here
                )
            landmarks = result.landmark_scan(options.confirm_corners)
            if landmarks is not None:
                yield landmarks
        pass_report.record(corners=front_end.summary())

    beams = scans[0].angles()
    field_of_view = float(np.rad2deg(beams[-1] - beams[0] + scans[0].angle_step_rad))
    rate = 1.0 / float(np.median(durations))
    noise = NoiseSpec(
        gyro_noise_density=mean_heading_density(model, increments, durations),
        odometry=model,
        landmark_sigma_m=float(
            np.sqrt(options.corner.covariance_scale)
            * np.hypot(options.corner.model_sigma_m, options.corner.range_sigma_m)
        ),
        landmark_field_of_view_deg=field_of_view,
        landmark_range_m=options.corner.max_range_m,
        rate_hz={"laser": rate, "odometry": rate},
    )
    metadata = {
        "source": str(path),
        "laser": options.laser,
        "laser_kinds": kinds,
        "laser_mounting": [float(value) for value in mounting],
        "laser_mounting_source": mounting_source,
        "odometry_source": source,
        "odometry_noise": model.as_dict(),
        "totals": {
            "laser_lines": len(chosen),
            "laser_lines_other": other,
            "odometry_lines": len(log.odometry),
            "scans_used": len(scans),
            "stale_odometry_runs": len(stale.runs),
            "comments": log.comments,
            **{f"skipped_{kind}": count for kind, count in sorted(log.skipped.items())},
        },
        "span_s": float(times[-1] - times[0]),
        "path_length_m": float(np.hypot(increments[:, 0], increments[:, 1]).sum()),
        "options": options.model_dump(mode="json"),
    }
    # rows dropped or repaired (workbench.degradations lists every non-zero one)
    counts = {
        "scan_stamps_reread": int(len(repair.reread)),
        "scan_lines_dropped_out_of_order": int(len(repair.dropped)),
        "scan_lines_dropped_duplicate": int(len(repair.duplicates)),
        "odom_stamps_reread": 0 if odo_repair is None else int(len(odo_repair.reread)),
        "odom_lines_dropped_out_of_order": 0
        if odo_repair is None
        else int(len(odo_repair.dropped)),
        "odom_lines_dropped_duplicate": 0
        if odo_repair is None
        else int(len(odo_repair.duplicates)),
        "stale_odometry_scans_spread": stale.scans if options.stale_odometry == "spread" else 0,
    }
    sequence = Sequence(
        name=name,
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        stream=stream,
        ground_truth=None,
        noise=noise,
        initial_state=InitialState(
            t=float(times[0]),
            position=np.zeros(2),
            rotation=np.array(0.0),
            velocity=np.zeros(2),
            velocity_sigma_m_s=0.5,
        ),
        metadata=metadata,
        reference_source=None,
        warnings=tuple(warnings),
        counts=counts,
        pass_report=pass_report,
    )
    return sequence, front_end
