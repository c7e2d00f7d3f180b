"""Cost of the GTSAM smoothers (prints figures; not a test).

1. iSAM2 time per keyframe on ``sim:circle`` with 10, 50 and 200 landmarks, split into the
   time inside GTSAM's ``update`` call and our Python-side overhead (factor construction,
   association bookkeeping, estimate extraction, causal marginal covariances).
2. The 3-D landmark factor: native ``BearingRangeFactor3D`` versus the exact Python
   ``CustomFactor`` (``landmark_factor=cartesian``), same run.
3. Fixed-lag time per keyframe with 1,000 versus 5,000 keyframes (flat if the window works).
4. iSAM2 on the whole Victoria Park run (``--parts victoria``).
5. iSAM2 with the newest keyframe and the landmarks just seen kept in the root clique
   (``smoothers.backends.eliminated_last``) against GTSAM's default elimination order, on
   60 s of ``sim:aghili-rover``, alternating in one process (``--parts ordering``).
6. Optionally (``--kitti``) iSAM2 on the whole kitti-imu-gps run, per fifth of the run.

Usage: ``python benchmarks/bench_smoother.py [--quick] [--kitti]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from smoothers.modes import SmootherFixedLag, SmootherIsam2
from workbench.registry import load_dataset


def timed_run(estimator_class, config, sequence) -> dict[str, float | np.ndarray]:
    """Run and time: per keyframe (wall) total and inside-GTSAM seconds."""
    estimator = estimator_class(config, sequence)
    update_seconds: list[float] = []
    keyframe_seconds: list[float] = []
    inner = estimator.backend.update

    def update(*args):
        elapsed = inner(*args)
        update_seconds.append(elapsed)
        return elapsed

    estimator.backend.update = update
    clock = time.perf_counter
    pending = 0.0
    count = len(update_seconds)
    for measurement in sequence.measurements():
        start = clock()
        estimator.process(measurement)
        pending += clock() - start
        if len(update_seconds) != count:  # a keyframe was committed in this call
            keyframe_seconds.append(pending)
            pending = 0.0
            count = len(update_seconds)
    start = clock()
    estimator.estimate()
    finish = clock() - start
    return {
        "keyframes": len(estimator.keyframe_t),
        "per_keyframe": np.array(keyframe_seconds),
        "update": np.array(update_seconds[: len(keyframe_seconds)]),
        "finish": finish,
        "landmarks": len(estimator.landmarks),
    }


def summary(label: str, result: dict) -> None:
    total = result["per_keyframe"]
    inside = result["update"]
    outside = total - inside
    print(
        f"{label:38s} keyframes {result['keyframes']:5d}  landmarks {result['landmarks']:4d}  "
        f"per keyframe median {1e3 * np.median(total):7.2f} ms  p99 {1e3 * np.percentile(total, 99):7.2f} ms  "
        f"inside update {1e3 * np.median(inside):6.2f} ms  python-side {1e3 * np.median(outside):6.2f} ms "
        f"({100 * outside.sum() / total.sum():4.1f} % of the total)  final {result['finish']:.2f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    parser.add_argument(
        "--kitti", action="store_true", help="also time the whole kitti-imu-gps run"
    )
    parser.add_argument(
        "--parts",
        default="landmarks,factor,lag",
        help="comma list of: landmarks, factor, lag, victoria, ordering",
    )
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    duration = "5" if args.quick else "10"

    if "landmarks" in parts:
        landmark_scaling(duration)
    if "factor" in parts:
        factor_comparison(duration)
    if "lag" in parts:
        fixed_lag_growth(args.quick)
    if "victoria" in parts:
        victoria_park()
    if "ordering" in parts:
        root_ordering(rounds=1 if args.quick else 2)
    if args.kitti:
        kitti_growth()


def root_ordering(rounds: int) -> None:
    """The same iSAM2 run with the root-clique ordering and with GTSAM's default order."""
    from smoothers import backends

    print("== iSAM2 on sim:aghili-rover (60 s, seed 0): root-clique ordering vs GTSAM's order")
    sequence = load_dataset("sim:aghili-rover", 0, {"duration_s": "60"})
    ours = backends.eliminated_last
    totals: dict[str, list[float]] = {"root ordering": [], "GTSAM order": []}
    for _ in range(rounds):
        for label, rule in (("root ordering", ours), ("GTSAM order", lambda keys: None)):
            backends.eliminated_last = rule
            try:
                result = timed_run(SmootherIsam2, SmootherIsam2.Config(), sequence)
            finally:
                backends.eliminated_last = ours
            summary(label, result)
            totals[label].append(float(np.sum(result["per_keyframe"])))
    ratio = np.median(totals["GTSAM order"]) / np.median(totals["root ordering"])
    print(f"  keyframe time, GTSAM order over root ordering: {ratio:.2f}x")


def victoria_park() -> None:
    """The whole Victoria Park run (planar, odometry + ids): iSAM2 time per keyframe."""
    print("== iSAM2 on victoria-park (keyframe at every scan)")
    sequence = load_dataset("victoria-park", 0, {})
    summary("isam2 victoria-park", timed_run(SmootherIsam2, SmootherIsam2.Config(), sequence))


def landmark_scaling(duration: str) -> None:
    """Every landmark of sim:circle is in view at every scan: the dense worst case."""
    print(
        "== iSAM2 on sim:circle (10 Hz scans, 100 Hz IMU, all landmarks in view), time per keyframe"
    )
    for count in (10, 50, 200):
        sequence = load_dataset(
            "sim:circle", 1, {"duration_s": duration, "landmark_count": str(count)}
        )
        summary(
            f"isam2, {count} landmarks",
            timed_run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence),
        )
        summary(
            f"isam2, {count} landmarks, no causal cov",
            timed_run(
                SmootherIsam2, SmootherIsam2.Config(anchors=3, causal_covariances=False), sequence
            ),
        )


def factor_comparison(duration: str) -> None:
    print("== landmark factor: native BearingRangeFactor3D vs Python CustomFactor (50 landmarks)")
    sequence = load_dataset("sim:circle", 1, {"duration_s": duration, "landmark_count": "50"})
    for factor in ("bearing-range", "cartesian"):
        config = SmootherIsam2.Config(anchors=3, causal_covariances=False, landmark_factor=factor)
        summary(f"isam2, {factor}", timed_run(SmootherIsam2, config, sequence))


def fixed_lag_growth(quick: bool) -> None:
    print("== fixed lag (lag 2 s) on sim:circle with 30 landmarks: 1,000 vs 5,000 keyframes")
    lengths = (100.0, 500.0) if not quick else (20.0, 100.0)
    for length in lengths:
        sequence = load_dataset(
            "sim:circle", 1, {"duration_s": str(length), "landmark_count": "30"}
        )
        result = timed_run(
            SmootherFixedLag, SmootherFixedLag.Config(anchors=3, lag_s=2.0), sequence
        )
        summary(f"fixed-lag, {length:.0f} s", result)
        last = result["per_keyframe"][-500:]
        print(f"{'':38s} last 500 keyframes: median {1e3 * np.median(last):.2f} ms")


def kitti_growth() -> None:
    print("== iSAM2 on kitti-imu-gps (keyframe every 10 IMU samples), per fifth of the run")
    sequence = load_dataset("kitti-imu-gps", 1, {})
    result = timed_run(
        SmootherIsam2,
        SmootherIsam2.Config(keyframe_imu_stride=10, causal_covariances=False),
        sequence,
    )
    summary("isam2 kitti", result)
    update = result["update"]
    n = len(update)
    print(
        "  inside update, mean per fifth [ms]:",
        [round(1e3 * float(update[q * n // 5 : (q + 1) * n // 5].mean()), 2) for q in range(5)],
    )


if __name__ == "__main__":
    main()
