"""Victoria Park (Sydney) from the gtsam wheel's ``Data/victoria_park.txt``: dataset ``victoria-park``.

The file is GTSAM's ``load2D`` format (checked against ``gtsam/slam/dataset.cpp``):

- ``ODOMETRY i j dx dy dtheta c11 c12 c13 c22 c23 c33``: the relative pose of pose ``j`` in
  the frame of pose ``i`` (a ``Pose2`` between, GTSAM's [x, y, theta] order) and its
  covariance, upper triangle row by row. (GTSAM's ``NoiseFormatAUTO`` recognises this
  zero pattern as ``NoiseFormatCOV``: a covariance, not an information matrix. Every row
  of the file has ``diag(1e-4, 4e-6, 4e-6)``: 1 cm along, 2 mm across, 2 mrad per step.)
- ``LANDMARK i l x y v11 v12 v22``: landmark ``l`` seen from pose ``i`` at ``(x, y)`` in the
  robot frame, with the 2x2 covariance ``[[v11, v12], [v12, v22]]`` (0.4 m^2 on both axes
  in this file; GTSAM converts it to bearing/range, we keep the Cartesian covariance).

Pose and landmark indices share one key space (a new landmark takes the next free index),
so pose indices skip; every landmark line refers to the latest pose (checked while
reading: an error otherwise). There are 6968 odometry steps (about 4.0 km of path), 3640
sightings of 151 landmarks in 3331 scans, and no time stamps.

Time: pose ``k`` (k-th ``ODOMETRY`` line) is at ``t = k * step_s`` with the nominal step
``step_s = 0.2`` s (option). The file itself does not say; 0.2 s makes the mean speed
about 2.9 m/s (about 10 km/h), a plausible pace for the utility vehicle that drove the
park over roughly a quarter of an hour to half an hour. Any consistent choice only
rescales time: velocities and rates scale by 1/step, their integrals do not change.

Stream at ``t_k`` (in this order): ``GyroSample(rate=[dtheta_k / step_s])``,
``Odometry(relative_pose=(dx, dy, dtheta), covariance, dt=step_s)``, then the
``LandmarkScan`` of every sighting from pose ``k`` (ids = the file's landmark indices, or
None with ``ids=false``). The gyro noise density stated in ``NoiseSpec`` is
``sigma_dtheta / sqrt(step_s)`` (so the integrated rate has the file's heading variance).
Ground truth: none exists for this recording (``ground_truth`` carries only ``scan_ids``,
the file's landmark indices, to score association).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.measurements import GyroSample, LandmarkScan, Measurement, Odometry, Sensor
from datasets.odometry_noise import OdometryNoiseModel, mean_heading_density, read_model_file
from datasets.options import describe_model, parse_options
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import GroundTruth, StateHistory
from datasets.text_files import text_lines


class VictoriaParkOptions(BaseModel):
    """``--data`` options of ``victoria-park``."""

    model_config = ConfigDict(extra="forbid")
    ids: bool = Field(
        True, description="attach the file's landmark indices to the scans (false: withheld)"
    )
    step_s: float = Field(
        0.2,
        gt=0,
        description="nominal time between consecutive poses [s] (the file has no time stamps)",
    )
    odometry_noise: str = Field(
        "calibrated",
        description="odometry noise: 'calibrated' (VICTORIA_PARK_ODOMETRY, fitted by `workbench "
        "calibrate-noise victoria-park` against the batch smoother: the file's own covariance is "
        "optimistic), 'file' (the file's diag(1e-4, 4e-6, 4e-6) per step), or a YAML model file",
    )
    max_steps: int | None = Field(
        None, gt=0, description="use only the first max_steps odometry steps"
    )
    path: str | None = Field(
        None,
        description="another file in the same format (default: the gtsam wheel's Data/victoria_park.txt)",
    )


VICTORIA_PARK_ODOMETRY = OdometryNoiseModel(
    np.array(
        [
            [5.57e-6, 1.66e-5, 2.46e-7],  # per second: x [m^2/s], y [m^2/s], theta [rad^2/s]
            [0.0, 0.0, 7.52e-6],  # per metre: [m^2/m, m^2/m, rad^2/m]
            [0.0, 0.0, 9.44e-4],  # per radian turned: [m^2/rad, m^2/rad, rad^2/rad]
        ]
    ),
    "calibrated: `workbench calibrate-noise victoria-park --data odometry_noise=file "
    "--iterations 4` (5 s windows against the batch smoother, 236 windows, 8 excluded)",
)
"""Victoria Park's odometry noise (there is no truth to fit it against). Fitted against the
batch smoother's estimate, re-run with each fit (4 rounds, starting from the file's noise;
``workbench.calibration.calibrate``): heading 0.031 rad per sqrt(rad) turned, 2.7 mrad per
sqrt(m) and 0.5 mrad per sqrt(s); 2.4 mm (along) and 4.1 mm (across) per sqrt(s). The
file's ``diag(1e-4, 4e-6, 4e-6)`` per 0.2 s step states 2 mrad per step whatever the turn:
at the first 1000 steps ekf-slam's mean NIS (2 dof) is 4.16 with it, 0.62 with this model.
The fit's own check (printed by the command): NEES per dof 0.35 / 1.42 / 12.9 (mean) on
1.25 / 5 / 20 s windows: the odometry's errors are correlated in time, which no white
model captures at every scale.
"""


def odometry_model(config: VictoriaParkOptions) -> OdometryNoiseModel | None:
    """The model ``config.odometry_noise`` names (None: the file's covariances)."""
    if config.odometry_noise == "file":
        return None
    if config.odometry_noise == "calibrated":
        return VICTORIA_PARK_ODOMETRY
    return read_model_file(Path(config.odometry_noise))


def default_path() -> Path:
    """The gtsam wheel's copy of ``victoria_park.txt``."""
    import gtsam

    return Path(gtsam.__file__).parent / "Data" / "victoria_park.txt"


def describe() -> list[str]:
    """Lines for ``workbench list --verbose``."""
    return ["victoria-park  --data options:"] + [
        "  " + line for line in describe_model(VictoriaParkOptions)
    ]


def load(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """Load ``victoria-park`` (no argument; ``seed`` unused: real data)."""
    config = parse_options(VictoriaParkOptions, options, "victoria-park --data")
    path = Path(config.path).expanduser() if config.path else default_path()
    return load_file(path, config)


def read_file(
    path: Path, max_steps: int | None = None
) -> tuple[np.ndarray, np.ndarray, list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]]:
    """Parse the file.

    Returns:
        increments (K, 3) (dx, dy, dtheta), covariances (K, 3, 3), and the scans as
        (step index k >= 1, ids (m,), points (m, 2), covariances (m, 2, 2)); step k is the pose
        reached by the k-th odometry line (k = 0 is the start pose).
    """
    increments: list[list[float]] = []
    covariances: list[np.ndarray] = []
    sightings: dict[int, list[tuple[int, list[float]]]] = {}
    pose_key: int | None = None
    for number, line in text_lines(path, "Victoria Park file"):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        tag = fields[0]
        expected = {"ODOMETRY": 12, "LANDMARK": 8}.get(tag)
        if expected is None:
            raise InputError(
                f"{path}:{number}: unknown tag '{tag}' (expected ODOMETRY or LANDMARK)"
            )
        if len(fields) != expected:
            raise InputError(
                f"{path}:{number}: {tag} needs {expected - 1} fields after the tag, got {len(fields) - 1}"
            )
        try:
            first, second = int(fields[1]), int(fields[2])
            values = [float(v) for v in fields[3:]]
        except ValueError:
            raise InputError(f"{path}:{number}: malformed number in '{line.strip()}'") from None
        if not all(np.isfinite(values)):
            raise InputError(f"{path}:{number}: non-finite value")
        if tag == "ODOMETRY":
            if max_steps is not None and len(increments) >= max_steps:
                break
            if pose_key is not None and first != pose_key:
                raise InputError(
                    f"{path}:{number}: odometry starts from pose {first} but the last pose is {pose_key}"
                )
            c = values[3:]
            cov = np.array([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]])
            if np.any(np.linalg.eigvalsh(cov) <= 0):
                raise InputError(f"{path}:{number}: odometry covariance is not positive definite")
            increments.append(values[:3])
            covariances.append(cov)
            pose_key = second
        else:
            current = pose_key if pose_key is not None else first
            if first != current:
                raise InputError(
                    f"{path}:{number}: landmark seen from pose {first} but the last pose is {current}"
                )
            cov = np.array([[values[2], values[3]], [values[3], values[4]]])
            if np.any(np.linalg.eigvalsh(cov) <= 0):
                raise InputError(f"{path}:{number}: landmark covariance is not positive definite")
            sightings.setdefault(len(increments), []).append((second, values))
    if not increments:
        raise InputError(f"{path}: no ODOMETRY lines")
    scans = []
    for step, entries in sorted(sightings.items()):
        ids = np.array([entry[0] for entry in entries], dtype=int)
        points = np.array([entry[1][:2] for entry in entries])
        covs = np.array([[[e[1][2], e[1][3]], [e[1][3], e[1][4]]] for e in entries])
        scans.append((step, ids, points, covs))
    return np.array(increments), np.array(covariances), scans


def load_file(path: Path, config: VictoriaParkOptions) -> Sequence:
    """Build the ``victoria-park`` ``Sequence`` from ``path``."""
    increments, covariances, raw_scans = read_file(path, config.max_steps)
    step = config.step_s
    model = odometry_model(config)
    if model is not None:
        covariances = np.array([model.increment_covariance(u, step) for u in increments])
    scans = [
        LandmarkScan(t=k * step, points=points, covariances=covs, ids=ids if config.ids else None)
        for k, ids, points, covs in raw_scans
    ]
    scan_ids = tuple((k * step, ids) for k, ids, _, _ in raw_scans)

    def stream() -> Iterator[Measurement]:
        scan_index = 0
        while scan_index < len(scans) and scans[scan_index].t <= 0.0:
            yield scans[scan_index]
            scan_index += 1
        for k, (increment, cov) in enumerate(zip(increments, covariances), start=1):
            t = k * step
            yield GyroSample(t=t, rate=np.array([increment[2] / step]))
            yield Odometry(t=t, covariance=cov, relative_pose=increment.copy(), dt=step)
            while scan_index < len(scans) and scans[scan_index].t <= t + 1e-9:
                yield scans[scan_index]
                scan_index += 1

    heading_sigma = float(np.sqrt(np.median(covariances[:, 2, 2])))
    all_ids = np.concatenate([ids for _, ids, _, _ in raw_scans]) if raw_scans else np.zeros(0, int)
    unique, counts = np.unique(all_ids, return_counts=True)
    return Sequence(
        name="victoria-park",
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.GYRO, Sensor.LANDMARKS}),
        stream=stream,
        ground_truth=GroundTruth(history=StateHistory(), scan_ids=scan_ids),
        noise=NoiseSpec(
            gyro_noise_density=heading_sigma / np.sqrt(step)
            if model is None
            else mean_heading_density(model, increments, np.full(len(increments), step)),
            odometry=model,
            landmark_sigma_m=float(
                np.sqrt(np.median(np.concatenate([c[:, 0, 0] for _, _, _, c in raw_scans])))
            )
            if raw_scans
            else None,
            rate_hz={"odometry": 1.0 / step, "gyro": 1.0 / step},
        ),
        initial_state=InitialState(
            t=0.0,
            position=np.zeros(2),
            rotation=np.array(0.0),
            velocity=np.zeros(2),
            velocity_sigma_m_s=0.5,
        ),
        metadata={
            "source": str(path),
            "step_s": step,
            "steps": int(len(increments)),
            "scans": len(scans),
            "sightings": int(len(all_ids)),
            "landmarks": int(len(unique)),
            "landmarks_seen_once": int((counts == 1).sum()),
            "path_length_m": float(np.hypot(increments[:, 0], increments[:, 1]).sum()),
            "time_stamps": "nominal: pose k at k * step_s (the file has none)",
            "options": config.model_dump(),
            "odometry_noise": "the file's covariances" if model is None else model.as_dict(),
        },
        landmark_ids=config.ids,
    )
