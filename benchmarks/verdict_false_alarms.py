"""False-alarm rate of the consistency verdict (``workbench.metrics.verdicts``) on tables of
perfectly consistent cells, per cell and per table (prints figures; not a test).

A consistent cell is simulated exactly: each run's per-step NEES is the squared norm of an
n-dimensional error that is standard normal at every step and AR(1)-correlated in time
(coefficient rho), so every step is chi-square(n) and steps of one run are dependent, as
an estimator's errors are. A table mixes the kinds of cells a consistency table holds:

    pose      n = 3 or 6, rho 0.99   (pose errors wander slowly)
    velocity  n = 2 or 3, rho 0.99
    gyro bias n = 1 or 3, rho 0.999  (a bias error lasts the whole run)
    accel bias n = 3,     rho 0.999
    map       n = 40..120 per snapshot, 30 snapshots, rho 0.9
    NIS       n = 4..30 per scan, independent scans

``python benchmarks/verdict_false_alarms.py [--tables 200] [--runs 10,25,50]`` prints, for
each run count, the fraction of cells and of 100-cell tables with a false alarm (a verdict
other than consistent).

Measured (this machine, 200 tables of 100 cells per run count, seed 0):
    see the issue note of the consistency issue for the figures of the committed level.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.signal import lfilter

from workbench.metrics.verdicts import Verdict, cell_statistic

CELL_KINDS = (
    # (name, dof choices, steps, rho, weight in a table)
    ("pose", (3, 6), 300, 0.99, 24),
    ("velocity", (2, 3), 300, 0.99, 16),
    ("gyro_bias", (1, 3), 300, 0.999, 16),
    ("accel_bias", (3,), 300, 0.999, 8),
    ("map", (40, 80, 120), 30, 0.9, 18),
    ("nis", (4, 10, 30), 300, 0.0, 18),
)


def consistent_runs(
    rng: np.random.Generator, runs: int, steps: int, dof: int, rho: float
) -> np.ndarray:
    """Per-step NEES (runs, steps), chi-square(dof) at every step, AR(1) in time."""
    noise = rng.normal(size=(runs, dof, steps))
    start = rng.normal(size=(runs, dof))
    errors = lfilter(
        [np.sqrt(1.0 - rho**2)], [1.0, -rho], noise, axis=-1, zi=(rho * start)[..., None]
    )[0]
    return (errors**2).sum(axis=1)


def simulate_table(rng: np.random.Generator, runs: int) -> tuple[int, int]:
    """(false alarms, cells) of one table of consistent cells."""
    alarms = cells = 0
    for _, dofs, steps, rho, weight in CELL_KINDS:
        for _ in range(weight):
            dof = int(rng.choice(dofs))
            nees = consistent_runs(rng, runs, steps, dof, rho)
            cell = cell_statistic(list(nees), [np.full(steps, dof)] * runs)
            cells += 1
            alarms += int(cell.verdict not in (Verdict.CONSISTENT, Verdict.TOO_FEW_RUNS))
    return alarms, cells


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--tables", type=int, default=200)
    parser.add_argument("--runs", default="10,25,50")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    for runs in (int(text) for text in args.runs.split(",")):
        results = [simulate_table(rng, runs) for _ in range(args.tables)]
        alarms = np.array([a for a, _ in results])
        cells = sum(c for _, c in results)
        print(
            f"runs={runs:3d}: per-cell false alarms {alarms.sum() / cells:.5f} "
            f"({alarms.sum()} of {cells}); tables with a false alarm {np.mean(alarms > 0):.3f} "
            f"(of {args.tables} tables of {cells // args.tables} cells)"
        )


if __name__ == "__main__":
    main()
