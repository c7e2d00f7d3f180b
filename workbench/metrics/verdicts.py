"""A verdict per consistency cell: ``consistent``, ``optimistic``, ``conservative`` or
``too few runs``, from where the cell's statistic lies against its band.

The unit of independence is the run. A cell (one block of one estimator on one dataset)
has M runs; run m contributes the sum of its NEES (or NIS) values ``S_m`` over its steps and
the sum of their degrees of freedom ``D_m``, and its normalised statistic
``s_m = S_m / D_m`` (1 for a consistent estimator on average). The cell's statistic is the
mean over runs ``s = mean_m s_m``.

Under consistency each step's value is chi-square with its dof, but the steps of one run
are correlated in time (a bias error lasts), so ``s_m`` is far more variable than a
chi-square with ``D_m`` dof would be. The band uses a chi-square with an *effective* dof per run (Satterthwaite):
``nu = D / tau`` with ``tau`` the integrated autocorrelation time of the normalised
per-step values ``x_k = NEES_k / dof_k`` (under consistency each has mean 1 and variance
``2 / dof``; only their correlation in time is unknown), estimated from all runs pooled
around the grand mean (Geyer's initial positive sequence, the finite-run weights
``1 - h / K``), and clipped to ``[min per-step dof, D]``: a run cannot vary more than one of
its steps (perfect correlation) nor less than all of them independent. The band is then
``chi2.ppf([a/2, 1 - a/2], M nu) / (M nu)`` at the cell level ``a``. A single value per
run (the final map of a smoother) is the exact case: ``nu = D`` and the band is the
chi-square band of the summed NEES.

Why these levels: a table holds dozens of cells, so a per-cell level of 5 % would flag some
cell of a perfectly consistent estimator almost surely. ``benchmarks/verdict_false_alarms.py``
simulates tables of consistent cells (time-correlated NEES, 1 to 6 dof, 10 to 50 runs) and
measures the rule's false-alarm rate per cell and per table; the levels keep a 100-cell
table of consistent cells below 5 %. Measured with 1000 tables each: 1e-4 per cell gives
0.03 % of cells and 3.1 % of tables at 20 runs, 0.02 % and 2.1 % at 50 runs; below 20 runs
the estimated correlation time is too often too short, and 1e-6 per cell gives 0.007 % and
0.7 % at 10 runs, 0.003 % and 0.3 % at 15.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from workbench.metrics.consistency import per_dof_band

MIN_RUNS = 10
"""Fewer runs decide nothing: the cell reads ``too few runs`` (per-step NEES cells)."""

MIN_POOLED_UPDATES = 200
"""Innovations decide from this many updates at any run count (``cell_statistic``'s
``pooled``): the innovation sequence of a consistent filter is white (zero mean, each
update independent of the earlier ones: Bar-Shalom, Li and Kirubarajan 2001, section
5.4.2), so the NIS summed over every update of one run is the chi-square of its summed dof
and its band narrows with the updates, not the runs. A NIS of 0.305 per dof over thousands
of Victoria Park updates is conservative from one run."""

CELL_FALSE_ALARM = 1e-4
"""Two-sided level of one cell's band with ``FEW_RUNS`` runs or more (module docstring)."""

FEW_RUNS = 20
FEW_RUNS_FALSE_ALARM = 1e-6
"""The level below ``FEW_RUNS`` runs: the correlation time estimated from 10-19 runs is too
often too short, and only a smaller level keeps a whole table's false alarms below 5 %."""


def cell_level(runs: int) -> float:
    """The two-sided level of a cell's band for ``runs`` runs."""
    return CELL_FALSE_ALARM if runs >= FEW_RUNS else FEW_RUNS_FALSE_ALARM


class Verdict(enum.StrEnum):
    CONSISTENT = "consistent"
    OPTIMISTIC = "optimistic"
    """the errors exceed what the covariance claims (NEES too large)"""
    CONSERVATIVE = "conservative"
    """the covariance claims more error than there is (NEES too small)"""
    TOO_FEW_RUNS = "too few runs"


@dataclass(frozen=True)
class CellStatistic:
    """A consistency cell.

    Attributes:
        value: mean over runs of the per-run NEES (or NIS) per dof (1 is consistent).
        lower, upper: the band of ``value`` for a consistent estimator (module docstring).
        verdict: where ``value`` lies against the band (``too few runs`` below ``MIN_RUNS``).
        runs: M. effective_dof: nu, the effective chi-square dof of one run.
    """

    value: float
    lower: float
    upper: float
    verdict: Verdict
    runs: int
    effective_dof: float


def integrated_autocorrelation_time(series: list[np.ndarray]) -> float:
    """``tau = 1 + 2 sum_h (1 - h/K) rho_h`` of per-step values, pooled over runs.

    Args:
        series: one array of normalised per-step values per run (lengths may differ).

    Returns:
        tau in ``[1, K]`` (K the longest run); 1 for a single step.
    """
    longest = max((len(values) for values in series), default=0)
    if longest < 2:
        return 1.0
    mean = float(np.mean(np.concatenate(series)))
    size = 1 << int(np.ceil(np.log2(2 * longest)))
    covariance = np.zeros(longest)
    counts = np.zeros(longest)
    for values in series:
        centred = np.asarray(values, dtype=float) - mean
        spectrum = np.fft.rfft(centred, n=size)
        lagged = np.fft.irfft(spectrum * np.conj(spectrum), n=size)[: len(centred)]
        covariance[: len(centred)] += lagged
        counts[: len(centred)] += len(centred) - np.arange(len(centred))
    valid = counts > 0
    covariance[valid] /= counts[valid]
    if covariance[0] <= 0.0:
        return float(longest)
    rho = covariance / covariance[0]
    tau = 1.0
    for lag in range(1, longest - 1, 2):
        pair = rho[lag] + rho[lag + 1]
        if pair <= 0.0:  # Geyer: stop at the first non-positive pair
            break
        tau += 2.0 * (rho[lag] * (1 - lag / longest) + rho[lag + 1] * (1 - (lag + 1) / longest))
    return float(np.clip(tau, 1.0, longest))


def cell_statistic(
    values: list[np.ndarray],
    dofs: list[np.ndarray],
    level: float | None = None,
    pooled: bool = False,
) -> CellStatistic | None:
    """The cell of M runs from each run's per-step NEES (or NIS) ``values[m]`` (K_m,) and
    their dof ``dofs[m]`` (K_m,) (module docstring). None without runs.

    ``pooled``: the values are innovations (NIS), white under consistency: the cell is
    judged at any run count once it pools ``MIN_POOLED_UPDATES`` updates (the correlation
    time is still estimated, so a correlated, inconsistent sequence widens its own band),
    at the few-runs level ``FEW_RUNS_FALSE_ALARM`` below ``FEW_RUNS`` runs.
    """
    runs_values, runs_dofs = [], []
    for run_values, run_dofs in zip(values, dofs, strict=True):
        run_values = np.asarray(run_values, dtype=float)
        run_dofs = np.asarray(run_dofs, dtype=float)
        keep = np.isfinite(run_values) & (run_dofs > 0)
        if np.any(keep):
            runs_values.append(run_values[keep])
            runs_dofs.append(run_dofs[keep])
    runs = len(runs_values)
    if runs == 0:
        return None
    totals = np.array([d.sum() for d in runs_dofs])
    per_run = np.array([v.sum() for v in runs_values]) / totals
    value = float(np.mean(per_run))
    tau = integrated_autocorrelation_time(
        [v / d for v, d in zip(runs_values, runs_dofs, strict=True)]
    )
    smallest = float(min(d.min() for d in runs_dofs))
    nu = float(np.clip(np.mean(totals) / tau, smallest, np.mean(totals)))
    level = cell_level(runs) if level is None else level
    lower, upper = (float(x) for x in per_dof_band(runs * nu, 1.0 - level))
    updates = sum(len(v) for v in runs_values)
    if runs < MIN_RUNS and not (pooled and updates >= MIN_POOLED_UPDATES):
        verdict = Verdict.TOO_FEW_RUNS
    elif value > upper:
        verdict = Verdict.OPTIMISTIC
    elif value < lower:
        verdict = Verdict.CONSERVATIVE
    else:
        verdict = Verdict.CONSISTENT
    return CellStatistic(value, float(lower), float(upper), verdict, runs, nu)
