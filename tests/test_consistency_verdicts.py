"""The units and bands of the consistency statistics (``workbench.metrics.verdicts``,
``state_errors.map_nees_series``) on synthetic runs whose distribution is known exactly."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.stats import chi2

from datasets.state import Frame, GroundTruth, LandmarkMap, StateHistory
from workbench.metrics.state_errors import landmark_nees_series, map_nees_series
from workbench.metrics.verdicts import (
    MIN_RUNS,
    Verdict,
    cell_statistic,
    integrated_autocorrelation_time,
)

LANDMARKS = 12
COMMON_SIGMA = 0.5  # the run's shared (vehicle/gauge) error of every landmark [m]
OWN_SIGMA = 0.1


def _map_run(rng: np.random.Generator, truth: np.ndarray) -> LandmarkMap:
    """One run's final map: every landmark off by a common offset plus its own error, with
    the joint covariance that says exactly that."""
    common = rng.normal(0.0, COMMON_SIGMA, 2)
    positions = truth + common + rng.normal(0.0, OWN_SIGMA, truth.shape)
    joint = COMMON_SIGMA**2 * np.kron(np.ones((LANDMARKS, LANDMARKS)), np.eye(2))
    joint += OWN_SIGMA**2 * np.eye(2 * LANDMARKS)
    return LandmarkMap.from_joint(np.arange(LANDMARKS), positions, joint, Frame.WORLD, 10.0)


@pytest.mark.study
def test_the_joint_map_band_covers_95_percent_and_the_per_landmark_band_does_not() -> None:
    rng = np.random.default_rng(0)
    truth_positions = rng.uniform(-10.0, 10.0, (LANDMARKS, 2))
    truth = GroundTruth(StateHistory(), LandmarkMap(np.arange(LANDMARKS), truth_positions))
    mapping = {i: i for i in range(LANDMARKS)}
    runs, trials = 20, 400
    joint_inside = landmark_inside = 0
    for _ in range(trials):
        maps = [_map_run(rng, truth_positions) for _ in range(runs)]
        joint = [map_nees_series((m,), mapping, truth) for m in maps]
        total, dof = sum(s.nees.sum() for s in joint), sum(s.dof.sum() for s in joint)
        low, high = chi2.ppf([0.025, 0.975], dof)
        joint_inside += low <= total <= high
        # the old unit: every landmark of every run as an independent 2-dof sample
        landmarks = [landmark_nees_series((m,), mapping, truth) for m in maps]
        total = sum(s.nees.sum() for s in landmarks)
        dof = sum(s.dof.sum() for s in landmarks)
        low, high = chi2.ppf([0.025, 0.975], dof)
        landmark_inside += low <= total <= high
    assert 0.92 <= joint_inside / trials <= 0.98
    assert landmark_inside / trials < 0.6


def _consistent_runs(rng, runs: int, steps: int, dof: int, rho: float, scale: float = 1.0):
    """Per-step NEES, chi-square(dof) at every step, AR(1)-correlated in time."""
    noise = rng.normal(size=(runs, dof, steps))
    start = rng.normal(size=(runs, dof))
    errors = lfilter([np.sqrt(1 - rho**2)], [1, -rho], noise, axis=-1, zi=(rho * start)[..., None])[
        0
    ]
    return scale * (errors**2).sum(axis=1)


@pytest.mark.parametrize(
    ("scale", "expected"),
    [(1.0, Verdict.CONSISTENT), (1.6, Verdict.OPTIMISTIC), (0.6, Verdict.CONSERVATIVE)],
)
def test_verdicts_of_synthetic_cells(scale: float, expected: Verdict) -> None:
    rng = np.random.default_rng(1)
    nees = _consistent_runs(rng, 25, 300, 3, 0.9, scale)
    cell = cell_statistic(list(nees), [np.full(300, 3)] * 25)
    assert cell.verdict == expected
    assert cell.lower < 1.0 < cell.upper
    assert cell.value == pytest.approx(nees.mean() / 3)


def test_fewer_than_ten_runs_decide_nothing() -> None:
    rng = np.random.default_rng(2)
    nees = _consistent_runs(rng, MIN_RUNS - 1, 100, 3, 0.0, 3.0)  # far off, but 9 runs
    assert (
        cell_statistic(list(nees), [np.full(100, 3)] * (MIN_RUNS - 1)).verdict
        == Verdict.TOO_FEW_RUNS
    )


def test_correlated_steps_widen_the_band_and_one_value_per_run_is_exact() -> None:
    rng = np.random.default_rng(3)
    independent = cell_statistic(
        list(_consistent_runs(rng, 30, 300, 2, 0.0)), [np.full(300, 2)] * 30
    )
    correlated = cell_statistic(
        list(_consistent_runs(rng, 30, 300, 2, 0.999)), [np.full(300, 2)] * 30
    )
    assert independent.upper - independent.lower < 0.2 * (correlated.upper - correlated.lower)
    single = cell_statistic([np.array([4.0])] * 30, [np.array([6])] * 30, level=0.05)
    np.testing.assert_allclose([single.lower, single.upper], chi2.ppf([0.025, 0.975], 180) / 180)


def test_integrated_autocorrelation_time_of_independent_and_constant_series() -> None:
    rng = np.random.default_rng(4)
    assert integrated_autocorrelation_time(list(rng.normal(size=(20, 500)))) < 1.3
    constant_per_run = [np.full(200, value) for value in rng.normal(size=20)]
    assert integrated_autocorrelation_time(constant_per_run) > 150


def test_innovations_are_judged_from_their_pooled_updates_at_any_run_count() -> None:
    """One run of white NIS: judged once it pools MIN_POOLED_UPDATES updates (a NIS of 0.3
    per dof over 500 updates is conservative, 3 optimistic, 1 consistent); fewer updates,
    or per-step NEES from one run, say too few runs."""
    from workbench.metrics.verdicts import MIN_POOLED_UPDATES, Verdict, cell_statistic

    rng = np.random.default_rng(0)
    dof = np.full(500, 2)
    white = rng.chisquare(2, size=500)
    verdicts = {
        scale: cell_statistic([scale * white], [dof], pooled=True).verdict
        for scale in (0.3, 1.0, 3.0)
    }
    assert verdicts == {
        0.3: Verdict.CONSERVATIVE,
        1.0: Verdict.CONSISTENT,
        3.0: Verdict.OPTIMISTIC,
    }
    few = MIN_POOLED_UPDATES - 1
    assert cell_statistic([white[:few]], [dof[:few]], pooled=True).verdict == Verdict.TOO_FEW_RUNS
    assert cell_statistic([0.3 * white], [dof]).verdict == Verdict.TOO_FEW_RUNS
