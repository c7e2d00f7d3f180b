"""``sim:laser2d``: a simulated 2-D laser indoors, through the same front end as the CARMEN logs.

The building is the simulator's ring corridor with door niches
(``datasets.simulation.floor_plan.ring_corridor_building``, the ``guerreiro-loop`` plan) and
the vehicle drives the ``guerreiro-loop`` path (about 60 m round the ring at 0.4 m/s, past
its start, so early corners are seen again). A SICK-like laser (``beams`` over
``field_of_view_deg``, mounted ``laser_offset_m`` ahead of the body origin) is ray-cast
against the walls at ``laser_rate_hz``: each range is the true distance along a beam whose
direction jitters by N(0, ``bearing_sigma_rad``^2) about its nominal angle, plus
N(0, ``range_sigma_m``^2). Wheel odometry between scans is the true increment plus noise
drawn from the stated covariance of an ``OdometryNoiseModel`` (the CARMEN logs' by default,
``datasets.carmen.noise``): model-matched.

The scans go through ``datasets.laser2d`` with the front end's defaults except what the
simulated sensor states exactly: the point noise (``range_sigma_m``, ``bearing_sigma_rad``),
no floor (``corner.model_sigma_m=0``) and unit scale (``corner.covariance_scale=1``), so the
corners' covariances are the first-order propagation alone and their NEES against the true
corners tests it (the real logs' floor and scale are for what real scans show beyond the
point model). The stream has the CARMEN loader's shape: at every scan after the first an
``Odometry(frame=True)`` increment, then the confirmed corners without ids.

Truth: poses at the scan times, the plan's corners (ids = vertex index), and the true corner
of every emitted detection (``scan_ids``, -1 for a detection more than
``TRUE_CORNER_TOLERANCE_M`` from every true corner). ``metadata['corner_nees']`` is the corners'
NEES against the truth (every corner extracted, and the emitted ones) with its chi-square
bounds.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.stats import chi2

from datasets.carmen.noise import CARMEN_ODOMETRY
from datasets.carmen.odometry import relative_increments
from datasets.errors import InputError
from datasets.laser2d.corners import Laser2dCornerSettings
from datasets.laser2d.frontend import Laser2dFrontEnd, Laser2dFrontEndSettings
from datasets.laser2d.scan import PlanarScan
from datasets.measurements import Measurement, Odometry, Sensor
from datasets.odometry_noise import mean_heading_density
from datasets.rotations import rot2_batch
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.simulation.assembly import sample_times
from datasets.simulation.floor_plan import FloorPlan, ring_corridor_building
from datasets.state import Frame, GroundTruth, LandmarkMap, StateHistory
from datasets.trajectory import Trajectory

TRUE_CORNER_TOLERANCE_M = 0.1
"""A detection within this of a true corner is that corner's [m]."""


class Laser2dScenarioOptions(BaseModel):
    """``--data`` options of ``sim:laser2d``."""

    model_config = ConfigDict(extra="forbid")

    duration_s: float | None = Field(
        None, gt=0, description="length [s]; default: the whole 60 m path at mean_speed_m_s"
    )
    mean_speed_m_s: float = Field(0.4, gt=0, le=2.0, description="mean speed on the path [m/s]")
    laser_rate_hz: float = Field(5.0, gt=0, le=100, description="scans per second")
    beams: int = Field(181, ge=3, description="beams per scan")
    field_of_view_deg: float = Field(180.0, gt=0, le=360, description="laser field of view [deg]")
    max_range_m: float = Field(20.0, gt=0, description="farthest return [m]")
    range_sigma_m: float = Field(0.01, ge=0, description="range noise std [m]")
    bearing_sigma_rad: float = Field(
        0.001, ge=0, description="std of each beam's direction about its nominal angle [rad]"
    )
    laser_offset_m: float = Field(
        0.1, description="the laser's offset ahead of the body origin along x [m]"
    )
    noise_scale: float = Field(
        1.0, ge=0, description="multiplies every drawn noise std (0: noise-free data)"
    )
    niche_depth_m: float | None = Field(
        None, gt=0, le=1.2, description="depth of every door niche [m] (default: the plan's)"
    )
    confirm_corners: bool = Field(
        True, description="emit only corners the previous scan confirmed (as on real logs)"
    )


def cast_planar_rays(
    walls: np.ndarray, origin: np.ndarray, directions: np.ndarray, max_range_m: float
) -> np.ndarray:
    """Distance from ``origin`` (2,) [m] along unit ``directions`` (n, 2) to the nearest wall
    of ``walls`` (M, 2, 2) [m], inf where none lies within ``max_range_m``."""
    start, edge = walls[:, 0], walls[:, 1] - walls[:, 0]
    offset = start - origin  # (M, 2)
    d_x, d_y = directions[:, 0:1], directions[:, 1:2]
    denominator = d_x * edge[None, :, 1] - d_y * edge[None, :, 0]  # (n, M)
    with np.errstate(divide="ignore", invalid="ignore"):
        along = (offset[None, :, 0] * edge[None, :, 1] - offset[None, :, 1] * edge[None, :, 0]) / (
            denominator
        )
        on_wall = (offset[None, :, 0] * d_y - offset[None, :, 1] * d_x) / denominator
    hit = (np.abs(denominator) > 1e-12) & (along > 0) & (on_wall >= 0) & (on_wall <= 1)
    distance = np.where(hit, along, np.inf).min(axis=1)
    return np.where(distance <= max_range_m, distance, np.inf)


def _corner_nees(
    errors: list[np.ndarray], covariances: list[np.ndarray]
) -> dict[str, float | int | None]:
    """Mean NEES per dof (2 dof each) of corner errors (k, 2) against covariances (k, 2, 2),
    with the two-sided 95 % chi-square bounds of the mean of that many."""
    if not errors or sum(len(e) for e in errors) == 0:
        return {"count": 0, "nees_per_dof": None, "lower": None, "upper": None}
    error, covariance = np.concatenate(errors), np.concatenate(covariances)
    nees = np.einsum("ni,nij,nj->n", error, np.linalg.inv(covariance), error)
    count = len(nees)
    return {
        "count": int(count),
        "nees_per_dof": float(nees.mean() / 2.0),
        "lower": float(chi2.ppf(0.025, 2 * count) / (2 * count)),
        "upper": float(chi2.ppf(0.975, 2 * count) / (2 * count)),
        "error_rms_m": float(np.sqrt(np.mean(np.sum(error**2, axis=1)))),
    }


def laser2d_scenario(seed: int, options: Laser2dScenarioOptions) -> Sequence:
    """Simulate ``sim:laser2d`` (module docstring) with noise ``seed``."""
    from datasets.simulation.guerreiro_motion import LOOP_PATH_LENGTH_M, guerreiro_loop_motion

    plan: FloorPlan = ring_corridor_building(niche_depth_m=options.niche_depth_m)
    motion = guerreiro_loop_motion(options.mean_speed_m_s)
    full = LOOP_PATH_LENGTH_M / options.mean_speed_m_s
    duration = options.duration_s if options.duration_s is not None else full
    if duration > full + 1e-9:
        raise InputError(f"sim:laser2d: duration_s={duration} exceeds the path's {full:.1f} s")
    times = sample_times(duration, options.laser_rate_hz)
    if len(times) < 2:
        raise InputError("sim:laser2d: fewer than two scans (raise duration_s)")
    kinematics = motion.kinematics(times)
    positions, headings = kinematics.position, np.asarray(kinematics.heading, dtype=float)
    generators = [np.random.default_rng(child) for child in np.random.SeedSequence(seed).spawn(3)]
    laser_rng, odometry_rng, _ = generators
    drawn = options.noise_scale

    half = np.deg2rad(options.field_of_view_deg) / 2.0
    angles = np.linspace(-half, half, options.beams)
    mounting = np.array([options.laser_offset_m, 0.0, 0.0])
    rotations = rot2_batch(headings)
    scans = []
    for t, position, heading, rotation in zip(times, positions, headings, rotations):
        jitter = laser_rng.standard_normal(len(angles)) * options.bearing_sigma_rad * drawn
        world_angles = heading + angles + jitter
        directions = np.column_stack([np.cos(world_angles), np.sin(world_angles)])
        origin = position + rotation @ mounting[:2]
        ranges = cast_planar_rays(plan.walls, origin, directions, options.max_range_m)
        ranges = ranges + laser_rng.standard_normal(len(ranges)) * options.range_sigma_m * drawn
        scans.append(
            PlanarScan(
                t=float(t),
                ranges=ranges,
                angles=angles,
                min_range_m=0.1,
                max_range_m=options.max_range_m,
                mounting=mounting,
            )
        )

    truth_poses = np.column_stack([positions, headings])
    true_increments = relative_increments(truth_poses)
    durations = np.diff(times)
    model = CARMEN_ODOMETRY
    covariances = np.array(
        [model.increment_covariance(u, dt) for u, dt in zip(true_increments, durations)]
    )
    draws = np.einsum(
        "kij,kj->ki",
        np.linalg.cholesky(covariances),
        odometry_rng.standard_normal((len(durations), 3)),
    )
    measured = true_increments + drawn * draws

    settings = Laser2dFrontEndSettings(
        corner=Laser2dCornerSettings(
            range_sigma_m=max(options.range_sigma_m, 1e-4),
            bearing_sigma_rad=max(options.bearing_sigma_rad, 1e-5),
            max_range_m=options.max_range_m,
            model_sigma_m=0.0,
            covariance_scale=1.0,
        ),
        confirm_corners=options.confirm_corners,
    )
    front_end = Laser2dFrontEnd(settings)
    results = [
        front_end.frame(
            k,
            scan,
            None if k == 0 else measured[k - 1],
            None if k == 0 else covariances[k - 1],
        )
        for k, scan in enumerate(scans)
    ]

    # truth of every detection: the nearest true corner in the body frame of the true pose
    all_errors, all_covariances, kept_errors, kept_covariances = [], [], [], []
    scan_ids: list[tuple[float, np.ndarray]] = []
    for result, position, rotation in zip(results, positions, rotations):
        corners = result.corners
        if len(corners.points) == 0:
            continue
        true_body = (plan.corners - position) @ rotation
        offsets = corners.points[:, None, :] - true_body[None, :, :]
        gaps = np.linalg.norm(offsets, axis=2)
        nearest = np.argmin(gaps, axis=1)
        rows = np.arange(len(nearest))
        good = gaps[rows, nearest] <= TRUE_CORNER_TOLERANCE_M
        ids = np.where(good, nearest, -1)
        errors = offsets[rows, nearest]
        all_errors.append(errors[good])
        all_covariances.append(corners.covariances[good])
        emitted = result.confirmed if options.confirm_corners else np.ones(len(ids), bool)
        kept_errors.append(errors[good & emitted])
        kept_covariances.append(corners.covariances[good & emitted])
        if emitted.any():
            scan_ids.append((float(result.t), ids[emitted].astype(int)))
    detections = sum(len(result.corners.points) for result in results)
    correct = sum(len(errors) for errors in all_errors)
    corner_nees = {
        "extracted": _corner_nees(all_errors, all_covariances),
        "emitted": _corner_nees(kept_errors, kept_covariances),
        "detections": int(detections),
        "false_detections": int(detections - correct),
    }

    def stream() -> Iterator[Measurement]:
        for index, result in enumerate(results):
            if index:
                yield Odometry(
                    t=result.t,
                    covariance=covariances[index - 1],
                    relative_pose=measured[index - 1].copy(),
                    dt=float(durations[index - 1]),
                    frame=True,
                )
            landmarks = result.landmark_scan(options.confirm_corners)
            if landmarks is not None:
                yield landmarks

    pose = Trajectory(t=times.copy(), positions=positions.copy(), rotations=headings.copy())
    truth = GroundTruth(
        history=StateHistory(pose=pose),
        landmarks=LandmarkMap(
            ids=np.arange(len(plan.corners)), positions=plan.corners.copy(), frame=Frame.WORLD
        ),
        scan_ids=tuple(scan_ids),
    )
    return Sequence(
        name="sim:laser2d",
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        stream=stream,
        ground_truth=truth,
        noise=NoiseSpec(
            gyro_noise_density=mean_heading_density(model, measured, durations),
            odometry=model,
            landmark_sigma_m=options.range_sigma_m,
            landmark_field_of_view_deg=options.field_of_view_deg,
            landmark_range_m=options.max_range_m,
            rate_hz={"laser": options.laser_rate_hz, "odometry": options.laser_rate_hz},
        ),
        initial_state=InitialState(
            t=float(times[0]),
            position=positions[0].copy(),
            rotation=np.array(headings[0]),
            velocity=kinematics.velocity[0].copy(),
            velocity_sigma_m_s=0.1,
        ),
        metadata={
            "source": "simulator",
            "scenario": "laser2d",
            "seed": seed,
            "options": options.model_dump(mode="json"),
            "corner_nees": corner_nees,
            "corners": front_end.summary(),
            "path_length_m": float(np.hypot(true_increments[:, 0], true_increments[:, 1]).sum()),
        },
        reference_source="simulated truth",
    )
