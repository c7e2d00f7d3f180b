"""KITTI IMU + GPS from the gtsam wheel's Data folder: dataset ``kitti-imu-gps``.

Files (read as gtsam's ``IMUKittiExampleGPS`` reads them, checked against the files):

- ``KittiEquivBiasedImu.txt``: header ``Time dt accelX accelY accelZ omegaX omegaY omegaZ``,
  space separated, 100 Hz, time [s], specific force [m/s^2], rate [rad/s] in the body
  frame (z up at rest: accelZ about +9.8). The ``dt`` column equals the time difference
  to the previous row; the first row's ``dt`` is meaningless (it repeats the time) and the
  second row follows a 1.92 s gap, so the usable stream starts after that gap.
- ``KittiGps_converted.txt``: header ``Time,X,Y,Z``, comma separated, local metric
  coordinates [m] (z up), about 1 Hz.
- ``KittiEquivBiasedImu_metadata.txt``: body-to-IMU pose (must be identity: checked) and
  the continuous-time IMU sigmas (accelerometer, gyroscope, integration, bias walks).

Sequence: starts at the first GPS fix after the last IMU gap (> ``max_imu_gap_s``), which
is fix #1, the same start as gtsam's example (``first_gps_pose = 1``). Initial state:
position = that fix; velocity = difference to the next fix (the car is already moving at
about 9 m/s: gtsam's example comment "stationary at the beginning" is wrong, its velocity
prior sigma of 1000 m/s hides it) with sigma ``initial_velocity_sigma_m_s``; rotation:
heading from that velocity, roll = pitch = 0 (the road is nearly level: z spans 2.5 m over
about 1.6 km), sigma ``initial_rotation_sigma_rad``. These two fixes are never held out.

Held-out GPS: a fraction ``holdout_fraction`` of the remaining fixes, drawn with the run
seed, is removed from the stream and kept in ``GroundTruth.held_out_positions`` for the
``gps_holdout_rmse_m`` metric. There is no other ground truth (no poses).

Noise: the metadata's IMU densities; initial bias sigmas from gtsam's example prior
(accelerometer 0.1 m/s^2, gyroscope 5e-5 rad/s); GPS sigma from gtsam's example noise
(precision 1/0.07 per axis -> sigma sqrt(0.07) = 0.265 m); gravity 9.8 m/s^2 as in the
example (``Sequence.gravity_m_s2``).

gtsam's ``IMUKittiExampleGPS`` has a counter (``included_imu_measurement_count``) that is
never reset, so its bias between-factor sigma grows with the square root of *all* IMU
samples so far and the bias constraint weakens along the run. Nothing here repeats it: the
smoother's ``CombinedImuFactor`` takes the bias random walk over each keyframe interval
from the continuous density.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.measurements import GpsFix, ImuSample, Measurement, Sensor
from datasets.options import describe_model, parse_options
from datasets.rotations import quat_wxyz_from_matrix
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.simulation.imu import gtsam_data_folder
from datasets.state import GroundTruth, StateHistory
from datasets.text_files import text_lines
from datasets.truth_quality.assess import assess_trajectory

IMU_FILE = "KittiEquivBiasedImu.txt"
GPS_FILE = "KittiGps_converted.txt"
METADATA_FILE = "KittiEquivBiasedImu_metadata.txt"
METADATA_FIELDS = (
    "BodyPtx", "BodyPty", "BodyPtz", "BodyPrx", "BodyPry", "BodyPrz", "AccelerometerSigma", "GyroscopeSigma",
    "IntegrationSigma", "AccelerometerBiasSigma", "GyroscopeBiasSigma", "AverageDeltaT",
)  # fmt: skip
GRAVITY_M_S2 = 9.8
"""gtsam's example's gravity for this recording."""


class KittiImuGpsOptions(BaseModel):
    """``--data`` options of ``kitti-imu-gps``."""

    model_config = ConfigDict(extra="forbid")
    holdout_fraction: float = Field(
        0.2,
        ge=0.0,
        le=0.95,
        description="fraction of GPS fixes withheld from the stream for evaluation",
    )
    gps_sigma_m: float = Field(
        float(np.sqrt(0.07)),
        gt=0,
        description="GPS position std per axis [m] (gtsam example: variance 0.07)",
    )
    duration_s: float | None = Field(
        None, gt=0, description="use only the first duration_s seconds after the start"
    )
    max_imu_gap_s: float = Field(
        0.1,
        gt=0,
        description="an IMU gap longer than this before the start is skipped; after it, an error",
    )
    initial_velocity_sigma_m_s: float = Field(
        1.0, gt=0, description="std of the GPS-differenced initial velocity [m/s]"
    )
    initial_rotation_sigma_rad: float = Field(
        0.1, gt=0, description="std of the initial rotation (heading from GPS, level) [rad]"
    )
    folder: str | None = Field(
        None, description="folder with the three files (default: the gtsam wheel's Data folder)"
    )


def describe() -> list[str]:
    """Lines for ``workbench list --verbose``."""
    return ["kitti-imu-gps  --data options:"] + [
        "  " + line for line in describe_model(KittiImuGpsOptions)
    ]


def read_metadata(path: Path) -> dict[str, float]:
    """The metadata's named values; ``InputError`` naming the file and problem."""
    lines = [line.split() for _, line in text_lines(path, "KITTI metadata file") if line.strip()]
    if len(lines) < 2 or lines[0] != list(METADATA_FIELDS) or len(lines[1]) != len(METADATA_FIELDS):
        raise InputError(
            f"{path}:1: expected the header {' '.join(METADATA_FIELDS)} and one line of {len(METADATA_FIELDS)} values"
        )
    try:
        values = [float(text) for text in lines[1]]
    except ValueError:
        raise InputError(f"{path}:2: a value is not a number") from None
    return dict(zip(METADATA_FIELDS, values))


def _read_table(path: Path, header: str, separator: str | None, columns: int) -> np.ndarray:
    lines = [line for _, line in text_lines(path, "KITTI data file")]
    if not lines or lines[0].strip() != header:
        raise InputError(f"{path}:1: expected the header '{header}'")
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(separator)
        if len(fields) != columns:
            raise InputError(f"{path}:{number}: expected {columns} values, got {len(fields)}")
        try:
            row = [float(field) for field in fields]
        except ValueError:
            raise InputError(f"{path}:{number}: a value is not a number") from None
        if not all(np.isfinite(row)):
            raise InputError(f"{path}:{number}: non-finite value")
        rows.append(row)
    table = np.array(rows, dtype=float).reshape(-1, columns)
    if len(table) < 2:
        raise InputError(f"{path}: fewer than two data lines")
    steps = np.diff(table[:, 0])
    if np.any(steps <= 0):
        bad = int(np.flatnonzero(steps <= 0)[0]) + 3
        raise InputError(f"{path}:{bad}: time does not increase (duplicate or backwards)")
    return table


def read_imu(path: Path) -> np.ndarray:
    """IMU table (N, 8): time, dt, accel xyz [m/s^2], gyro xyz [rad/s]."""
    return _read_table(path, "Time dt accelX accelY accelZ omegaX omegaY omegaZ", None, 8)


def read_gps(path: Path) -> np.ndarray:
    """GPS table (M, 4): time, x, y, z [m]."""
    return _read_table(path, "Time,X,Y,Z", ",", 4)


def load(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """Load ``kitti-imu-gps`` (no argument; ``seed`` draws the held-out fixes)."""
    config = parse_options(KittiImuGpsOptions, options, "kitti-imu-gps --data")
    folder = Path(config.folder).expanduser() if config.folder else gtsam_data_folder()
    return load_folder(folder, seed, config)


def load_folder(folder: Path, seed: int, config: KittiImuGpsOptions) -> Sequence:
    """Build the sequence from the three files in ``folder``."""
    metadata = read_metadata(folder / METADATA_FILE)
    if any(abs(metadata[name]) > 1e-12 for name in METADATA_FIELDS[:6]):
        raise InputError(
            f"{folder / METADATA_FILE}:2: the body-to-IMU pose is not identity; only an IMU at the body origin is supported"
        )
    imu = read_imu(folder / IMU_FILE)
    gps = read_gps(folder / GPS_FILE)

    gaps = np.flatnonzero(np.diff(imu[:, 0]) > config.max_imu_gap_s)
    imu_start = imu[gaps[-1] + 1, 0] if len(gaps) else imu[0, 0]
    # The first fix at or after the IMU becomes continuous (gtsam's example: fix #1).
    first = int(np.searchsorted(gps[:, 0], imu_start))
    if first + 1 >= len(gps):
        raise InputError(
            f"{folder / GPS_FILE}: fewer than two GPS fixes after the IMU becomes continuous at t={imu_start:.3f} s"
        )
    t0 = gps[first, 0]
    end = gps[-1, 0] if config.duration_s is None else t0 + config.duration_s
    gps = gps[(gps[:, 0] >= t0) & (gps[:, 0] <= end)]
    if len(gps) < 2:
        raise InputError(
            f"kitti-imu-gps: duration_s={config.duration_s} leaves fewer than two GPS fixes"
        )
    # Keep the last IMU sample at or before t0 so the first interval is covered.
    keep_from = max(int(np.searchsorted(imu[:, 0], t0, side="right")) - 1, 0)
    imu = imu[keep_from:]
    imu = imu[imu[:, 0] <= end]

    velocity = (gps[1, 1:] - gps[0, 1:]) / (gps[1, 0] - gps[0, 0])
    heading = float(np.arctan2(velocity[1], velocity[0]))
    c, s = np.cos(heading), np.sin(heading)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    start = InitialState(
        t=float(t0),
        position=gps[0, 1:].copy(),
        rotation=quat_wxyz_from_matrix(rotation),
        velocity=velocity,
        position_sigma_m=config.gps_sigma_m,
        rotation_sigma_rad=config.initial_rotation_sigma_rad,
        velocity_sigma_m_s=config.initial_velocity_sigma_m_s,
    )

    rng = np.random.default_rng(seed)
    candidates = np.arange(2, len(gps))
    count = int(round(config.holdout_fraction * len(candidates)))
    held = np.zeros(len(gps), dtype=bool)
    held[np.sort(rng.choice(candidates, size=count, replace=False))] = True
    used_gps = gps[~held]
    held_gps = gps[held]

    gps_cov = np.eye(3) * config.gps_sigma_m**2
    rate = 1.0 / metadata["AverageDeltaT"]
    noise = NoiseSpec(
        gyro_noise_density=metadata["GyroscopeSigma"],
        accel_noise_density=metadata["AccelerometerSigma"],
        gyro_bias_walk=metadata["GyroscopeBiasSigma"],
        accel_bias_walk=metadata["AccelerometerBiasSigma"],
        gyro_bias_sigma_rad_s=5e-5,
        accel_bias_sigma_m_s2=0.1,
        gps_sigma_m=config.gps_sigma_m,
        rate_hz={"imu": rate, "gps": 1.0},
    )

    def stream() -> Iterator[Measurement]:
        i = j = 0
        while i < len(imu) or j < len(used_gps):
            if j >= len(used_gps) or (i < len(imu) and imu[i, 0] <= used_gps[j, 0]):
                row = imu[i]
                yield ImuSample(t=float(row[0]), gyro=row[5:8].copy(), accel=row[2:5].copy())
                i += 1
            else:
                row = used_gps[j]
                yield GpsFix(t=float(row[0]), position=row[1:4].copy(), covariance=gps_cov.copy())
                j += 1

    # held-out fixes are compared at their own stamps: only what removes fixes (a freeze, a
    # jump) is excluded (``datasets.truth_quality``), never a gap
    excluded, truth_warnings = assess_trajectory(
        held_gps[:, 0], held_gps[:, 1:4], None, "held-out GPS fixes", sampled_only=True
    )
    truth = GroundTruth(
        history=StateHistory(),
        held_out_positions=(held_gps[:, 0].copy(), held_gps[:, 1:4].copy()),
        excluded=excluded,
    )
    return Sequence(
        name="kitti-imu-gps",
        dimension=3,
        sensors=frozenset({Sensor.IMU, Sensor.GPS}),
        stream=stream,
        ground_truth=truth,
        noise=noise,
        initial_state=start,
        metadata={
            "source": str(folder),
            "seed": seed,
            "options": config.model_dump(),
            "gps_fixes_used": int(len(used_gps)),
            "gps_fixes_held_out": int(len(held_gps)),
            "start_t": float(t0),
        },
        reference_source="held-out GPS fixes",
        warnings=tuple(truth_warnings),
        gravity_m_s2=GRAVITY_M_S2,
    )
