"""Aghili adaptive R (eq. (42)) from a 10x wrong initial R, over seeds: the adapted landmark
std and the position RMSE against a filter given the true R, for the posterior-residual
form (default) and the prior form as printed.

Run: ``python benchmarks/bench_aghili_adaptive_r.py [--seeds 1-10] [--duration 60]``.
Scenario: ``sim:aghili-rover`` with every landmark's sigma 0.2 m, initial R = 10 x 0.04 m^2.
"""

from __future__ import annotations

import argparse

import numpy as np

from datasets.simulation.scenarios import load_scenario
from filters.aghili.filter import AghiliConfig, AghiliFilter

TRUE_SIGMA_M = 0.2


def position_rmse(sequence, estimate) -> float:
    truth = sequence.ground_truth.pose
    pose = estimate.causal.pose
    index = np.clip(np.searchsorted(truth.t, pose.t), 0, len(truth.t) - 1)
    return float(np.sqrt(np.mean(np.sum((pose.positions - truth.positions[index]) ** 2, axis=1))))


def run(sequence, **config) -> tuple[AghiliFilter, object]:
    f = AghiliFilter(AghiliConfig(**config), sequence)
    for measurement in sequence.measurements():
        f.process(measurement)
    return f, f.estimate()


def seed_range(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-10", help="seed range, e.g. 1-10")
    parser.add_argument("--duration", default="60", help="scenario length [s]")
    args = parser.parse_args()
    options = {
        "duration_s": args.duration,
        "landmark_sigma_min_m": str(TRUE_SIGMA_M),
        "landmark_sigma_max_m": str(TRUE_SIGMA_M),
    }
    print(
        f"{'seed':>4} {'form':>9} {'sigma_R [m] (x, y, z)':>24} {'ATE adapt':>10} {'ATE true R':>10} {'ratio':>6}"
    )
    ratios: dict[str, list[float]] = {"posterior": [], "prior": []}
    for seed in seed_range(args.seeds):
        sequence = load_scenario("aghili-rover", seed, options)
        _, reference = run(
            sequence, landmark_measurement_sigma_m=TRUE_SIGMA_M, adaptive_noise=False
        )
        reference_rmse = position_rmse(sequence, reference)
        for form in ratios:
            adaptive, estimate = run(
                sequence,
                landmark_measurement_sigma_m=TRUE_SIGMA_M * np.sqrt(10.0),
                adaptive_noise=True,
                adaptive_residual=form,
            )
            sigma = np.sqrt(np.diag(adaptive.noise_window.estimate()))
            rmse = position_rmse(sequence, estimate)
            ratios[form].append(rmse / reference_rmse)
            sigma_text = " ".join(f"{value:.3f}" for value in sigma)
            print(
                f"{seed:4d} {form:>9} {sigma_text:>24} {rmse:10.4f} {reference_rmse:10.4f} {rmse / reference_rmse:6.3f}",
                flush=True,
            )
    for form, values in ratios.items():
        print(
            f"{form}: ATE ratio median {np.median(values):.3f}, max {np.max(values):.3f}, within 10%: {np.mean(np.array(values) <= 1.1):.0%}"
        )


if __name__ == "__main__":
    main()
