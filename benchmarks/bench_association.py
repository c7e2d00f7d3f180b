"""JCBB cost versus the number of candidate pairings (individually compatible pairs).

A 2-D map of ``m`` landmarks on a grid is predicted with one shared uncertain offset (a
vehicle position error, ``common_sigma``) plus independent landmark noise; a scan measures
``k`` of them. Growing the common uncertainty grows the number of individually compatible
(measurement, landmark) pairs, which is what drives the interpretation tree. Prints, per
setting: candidate pairings, tree nodes, wall time, whether the node cap was hit, and the
pairs found correct. A regular grid is JCBB's worst case on purpose: once the common
uncertainty is comparable to the spacing, a whole-cell shift is jointly compatible too, so
the tree is large and "correct" drops (the answer is ambiguous, not a search failure).

    /work/venv/bin/python benchmarks/bench_association.py [--max-nodes 20000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from filters.association import DEFAULT_MAX_NODES, associate_jcbb


def _problem(
    rng: np.random.Generator, landmarks: int, measured: int, common_sigma: float, spacing: float
):
    side = int(np.ceil(np.sqrt(landmarks)))
    grid = (
        spacing
        * np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)[
            :landmarks
        ]
    )
    predicted = grid + 0.02 * rng.normal(size=grid.shape)
    joint = np.kron(np.full((landmarks, landmarks), common_sigma**2), np.eye(2)) + 0.05**2 * np.eye(
        2 * landmarks
    )
    chosen = rng.choice(landmarks, size=measured, replace=False)
    offset = common_sigma * rng.normal(size=2)
    z = grid[chosen] + offset + 0.05 * rng.normal(size=(measured, 2))
    return z, np.repeat((0.05**2 * np.eye(2))[None], measured, axis=0), predicted, joint, chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-nodes", type=int, default=DEFAULT_MAX_NODES)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"max_nodes={args.max_nodes}")
    print(
        f"{'m':>4} {'k':>4} {'sigma':>6} {'cand.pairs':>10} {'nodes':>8} {'ms':>9} {'capped':>6} {'correct':>8}"
    )
    for landmarks, measured in ((10, 5), (50, 10), (200, 15)):
        for common_sigma in (0.05, 0.2, 0.5, 1.0, 2.0):
            rng = np.random.default_rng(0)
            candidates = nodes = correct = pairs = 0
            capped = 0
            seconds = 0.0
            for _ in range(args.repeats):
                z, r, h, p, truth = _problem(rng, landmarks, measured, common_sigma, spacing=1.5)
                start = time.perf_counter()
                result = associate_jcbb(z, r, h, p, max_nodes=args.max_nodes)
                seconds += time.perf_counter() - start
                candidates += int(result.candidate_counts.sum())
                nodes += result.nodes
                capped += int(result.truncated)
                pairs += result.pairs
                correct += int((result.assignments == truth).sum())
            n = args.repeats
            print(
                f"{landmarks:>4} {measured:>4} {common_sigma:>6.2f} {candidates / n:>10.1f} {nodes / n:>8.0f} "
                f"{1e3 * seconds / n:>9.2f} {capped:>3}/{n:<2} {correct:>3}/{measured * n:<4}"
            )


if __name__ == "__main__":
    main()
