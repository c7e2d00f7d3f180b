"""Aghili filter cost: propagation and update steps per second with 10, 50, 200 landmarks.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_aghili.py`` (on a loaded 2-core box
multi-threaded BLAS makes mid-size products ~10x slower). Landmarks are placed directly in
the state (synthetic covariance), so the figures isolate the filter's own cost.
"""

from __future__ import annotations

import time

import numpy as np

from datasets.measurements import ImuSample, LandmarkScan
from datasets.simulation.scenarios import load_scenario
from filters.aghili import quaternion_jpl as quat
from filters.aghili.filter import AghiliConfig, AghiliFilter


def filter_with_landmarks(count: int) -> AghiliFilter:
    sequence = load_scenario("aghili-rover", 0, {"duration_s": "1"})
    f = AghiliFilter(AghiliConfig(adaptive_noise=False), sequence)
    rng = np.random.default_rng(count)
    for index in range(count):
        f._augment(rng.uniform(-15, 15, 3), np.eye(3) * 0.04, 10_000 + index)
    f.process(ImuSample(f.t + 0.05, np.zeros(3), np.array([0.0, 0.0, 9.81])))
    return f


def main() -> None:
    print(f"{'n':>5} {'propagation/s':>14} {'update/s (10 lm)':>17}")
    for count in (10, 50, 200):
        f = filter_with_landmarks(count)
        steps = 400
        gyro, accel = np.array([0.01, -0.02, 0.05]), np.array([0.1, 0.0, 9.81])
        start = time.perf_counter()
        for _ in range(steps):
            f.process(ImuSample(f.t + 0.05, gyro, accel))
        propagation_rate = steps / (time.perf_counter() - start)
        ids = np.array(f.landmark_ids[:10])
        updates = 50
        start = time.perf_counter()
        for _ in range(updates):
            body = (f.rho[:10] - f.r) @ quat.rotation_matrix(f.q)
            f.process(
                LandmarkScan(f.t, body, np.repeat(np.eye(3)[None] * 0.04, 10, axis=0), ids=ids)
            )
        update_rate = updates / (time.perf_counter() - start)
        print(f"{count:5d} {propagation_rate:14.0f} {update_rate:17.0f}")


if __name__ == "__main__":
    main()
