"""Cost of ekf-slam per step versus the number of mapped landmarks (prints a table).

The world-centric EKF is O(n^2) per update in the state size n = 3 + 2 m: prediction
touches only the vehicle rows (O(n)), but every update and every landmark initialisation
rewrites the full covariance. Run: ``python benchmarks/bench_ekf_slam.py``.
(Set OPENBLAS_NUM_THREADS=1 on a shared machine: small matrix products do not gain from
threads and suffer from contention.)
"""

from __future__ import annotations

import time

import numpy as np

from datasets.measurements import LandmarkScan, Odometry, Sensor
from datasets.rotations import rot2
from datasets.sequence import InitialState, Sequence
from filters.ekf_slam.config import EkfSlamConfig
from filters.ekf_slam.filter import EkfSlam


def timed_run(
    landmark_count: int, association: str, steps: int = 200, seed: int = 0
) -> tuple[float, float]:
    """Seconds per odometry step and per scan (5 sightings) with ``landmark_count`` mapped."""
    rng = np.random.default_rng(seed)
    landmarks = rng.uniform(-50, 50, size=(landmark_count, 2))
    cov = np.eye(2) * 0.01
    sequence = Sequence(
        name="bench",
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        stream=lambda: iter(()),
        initial_state=InitialState(t=0.0, position=np.zeros(2), rotation=np.array(0.0)),
    )
    estimator = EkfSlam(EkfSlamConfig(association=association), sequence)
    estimator.process(
        LandmarkScan(
            t=0.0,
            points=landmarks,
            covariances=np.repeat(cov[None], landmark_count, 0),
            ids=np.arange(landmark_count),
        )
    )
    pose = np.zeros(3)
    odo_seconds = scan_seconds = 0.0
    for k in range(1, steps + 1):
        increment = np.array([0.1, 0.0, 0.01])
        pose = np.array([*pose[:2] + rot2(pose[2]) @ increment[:2], pose[2] + increment[2]])
        start = time.perf_counter()
        estimator.process(
            Odometry(
                t=0.1 * k, covariance=np.diag([1e-4, 1e-4, 1e-5]), relative_pose=increment, dt=0.1
            )
        )
        odo_seconds += time.perf_counter() - start
        seen = rng.choice(landmark_count, size=5, replace=False)
        body = (landmarks[seen] - pose[:2]) @ rot2(pose[2]) + rng.normal(scale=0.1, size=(5, 2))
        scan = LandmarkScan(
            t=0.1 * k,
            points=body,
            covariances=np.repeat(cov[None], 5, 0),
            ids=seen if association == "ids" else None,
        )
        start = time.perf_counter()
        estimator.process(scan)
        scan_seconds += time.perf_counter() - start
    return odo_seconds / steps, scan_seconds / steps


def main() -> None:
    print(
        f"{'landmarks':>9} {'assoc':>5} {'odometry step [ms]':>19} {'scan (5 sightings) [ms]':>24}"
    )
    for count in (10, 50, 100, 200, 400):
        for association in ("ids", "jcbb"):
            odometry, scan = timed_run(count, association)
            print(f"{count:>9} {association:>5} {odometry * 1e3:>19.3f} {scan * 1e3:>24.3f}")


if __name__ == "__main__":
    main()
