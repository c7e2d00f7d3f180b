"""Cost of the sensor-based filter versus the number of landmarks in the state (10, 50, 200).

A planar vehicle turning slowly among ``L`` landmarks: the first scan sees all of them
(they all enter the state), later scans see 10 of them. Prints milliseconds per gyro
prediction step and per scan (association + update + management), for JCBB association
and for known ids. The prediction is O(n^2) (block-structured F P F^T), the update
O(n^2 m).

    /work/venv/bin/python benchmarks/bench_sensor_based.py [--steps 200] [--dimension 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from datasets.measurements import GyroSample, LandmarkScan, Sensor
from datasets.sequence import InitialState, NoiseSpec, Sequence
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam


def _scene(landmarks: int, d: int, rng: np.random.Generator) -> np.ndarray:
    radius = rng.uniform(2.0, 15.0, landmarks)
    angle = rng.uniform(-np.pi, np.pi, landmarks)
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    if d == 3:
        points = np.column_stack([points, rng.uniform(-1.0, 2.0, landmarks)])
    return points


def _time(landmarks: int, d: int, steps: int, association: str) -> tuple[float, float]:
    rng = np.random.default_rng(0)
    world = _scene(landmarks, d, rng)
    r = 1 if d == 2 else 3
    sequence = Sequence(
        name="bench",
        dimension=d,
        sensors=frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
        stream=lambda: iter(()),
        noise=NoiseSpec(gyro_noise_density=1e-3, gyro_bias_sigma_rad_s=0.01),
        initial_state=InitialState(
            t=0.0,
            position=np.zeros(d),
            rotation=np.array(0.0) if d == 2 else np.array([1.0, 0, 0, 0]),
            velocity=np.zeros(d),
        ),
    )
    config = SensorBasedConfig(
        association=association,
        max_landmarks=max(200, landmarks),
        in_view_range_m=1.0,
        min_observations=1,
    )
    estimator = SensorBasedSlam(config, sequence)
    rate = np.zeros(r)
    rate[-1] = 0.05
    sigma = 0.05
    dt = 0.1
    predict_seconds = scan_seconds = 0.0
    for k in range(steps + 1):
        t = k * dt
        heading = rate[-1] * t
        c, s = np.cos(heading), np.sin(heading)
        rotation = np.eye(d)
        rotation[:2, :2] = [[c, -s], [s, c]]
        body = world @ rotation
        visible = (
            np.arange(landmarks)
            if k == 0
            else rng.choice(landmarks, size=min(10, landmarks), replace=False)
        )
        points = body[visible] + sigma * rng.normal(size=(len(visible), d))
        scan = LandmarkScan(
            t=t,
            points=points,
            covariances=np.repeat((sigma**2 * np.eye(d))[None], len(visible), 0),
            ids=visible,
        )
        start = time.perf_counter()
        estimator.process(GyroSample(t=t, rate=rate.copy()))
        middle = time.perf_counter()
        estimator.process(scan)
        end = time.perf_counter()
        if k > 0:
            predict_seconds += middle - start
            scan_seconds += end - middle
    return (
        1e3 * predict_seconds / steps,
        1e3 * scan_seconds / steps,
        len(estimator.state.landmark_ids()),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--dimension", type=int, choices=[2, 3], default=2)
    args = parser.parse_args()
    print(f"dimension {args.dimension}, {args.steps} steps, 10 landmarks visible per scan")
    print(
        f"{'landmarks':>9} {'assoc':>6} {'in state':>8} {'predict ms':>11} {'scan ms':>9} {'total ms/step':>14}"
    )
    for landmarks in (10, 50, 200):
        for association in ("ids", "jcbb"):
            predict, scan, in_state = _time(landmarks, args.dimension, args.steps, association)
            print(
                f"{landmarks:>9} {association:>6} {in_state:>8} {predict:>11.3f} {scan:>9.3f} {predict + scan:>14.3f}"
            )


if __name__ == "__main__":
    main()
