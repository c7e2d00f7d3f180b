"""Ranked association hypotheses of one scan, for estimators that keep several.

A *hypothesis* assigns every sighting of a scan either to a distinct map landmark or to a
new landmark. Its score is the log likelihood of the scan under it, the hypothesis
probability of multiple hypothesis tracking (Reid 1979, eq. 16; for a landmark map, Cox and
Leonard 1994, section 3) without a clutter term, the missed-detection term optional
(``detection``, below):

    log L = log N(nu; 0, S) + n_new * log(lambda_new)
            [+ sum_paired log P_D + sum_(in view, unpaired) log(1 - P_D)]

- ``nu`` (p*d,): the stacked innovations of the p paired sightings, ``S`` their *joint*
  covariance ``H P H^T + R`` (the pose error correlates the sightings of one scan);
- ``lambda_new`` [1/m^d]: the density, in the sighting space, of a sighting of a landmark not
  yet mapped (``new_landmark_log_density`` is its natural logarithm).

The hypotheses are enumerated best first with Murty's k-best assignment algorithm (Murty
1968) on per-sighting costs ``-log N(nu_ji; 0, S_ji)`` (each pair's own block, an
approximation that ignores the correlation), with ``scipy.optimize.linear_sum_assignment``
solving each assignment. A pair is a candidate when it lies inside the individual chi-square
gate at ``gate_probability``. The enumerated ones are then rescored with the joint
likelihood above and re-sorted, so the ranking that leaves this module is the exact one
among those enumerated.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dpotrf, dtrtrs
from scipy.optimize import linear_sum_assignment

from filters.association.compatibility import chi2_gate
from filters.association.policy import Decision, Predictor, ScanAssociation

MURTY_OVERSAMPLING = 2
"""Hypotheses enumerated per hypothesis returned: the joint rescoring can reorder them."""


@dataclass(frozen=True)
class ScanHypothesis:
    """One joint interpretation of a scan.

    Attributes:
        log_likelihood: ``log L`` above (natural log; densities in 1/m^d).
        candidates: (k,) the candidate index each sighting pairs with, -1 for a new landmark.
        individual_nis: (k,) ``D^2`` of each pair with its own block (d dof), NaN for new.
    """

    log_likelihood: float
    candidates: np.ndarray
    individual_nis: np.ndarray

    def association(self, measured_cov: np.ndarray) -> ScanAssociation:
        """The hypothesis as the policy's ``ScanAssociation`` (mode ``multi-hypothesis``):
        each sighting matched or new, used with its own noise."""
        candidates = np.asarray(self.candidates, dtype=int)
        decisions = tuple(Decision.MATCHED if c >= 0 else Decision.NEW for c in candidates)
        return ScanAssociation(
            "multi-hypothesis",
            decisions,
            candidates.copy(),
            ("",) * len(candidates),
            self.individual_nis.copy(),
            np.array(measured_cov, dtype=float),
            np.ones(len(candidates)),
        )


def ranked_hypotheses(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    candidate_count: int,
    predictor: Predictor,
    *,
    gate_probability: float,
    new_landmark_log_density: float,
    count: int,
    detection: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
) -> list[ScanHypothesis]:
    """The ``count`` most likely hypotheses of a scan, best first (module docstring).

    Args:
        measured: (k, d) sightings. measured_cov: (k, d, d) their covariances.
        candidate_count: m map landmarks; the predictor answers for indices 0..m-1.
        gate_probability: a pair outside this individual chi-square gate is no candidate.
        new_landmark_log_density: ``log(lambda_new)``, lambda_new in 1/m^d.
        count: how many to return (at least one: all sightings new is always feasible).
        detection: predicted sightings (m, d) -> (``P_D`` (m,), inside the sensor's view
            (m,) bool): the missed-detection term, each pairing ``log P_D`` and each landmark
            in view left unpaired ``log(1 - P_D)`` (Reid 1979, eq. 16). None: no such term.
    """
    measured = np.asarray(measured, dtype=float)
    measured_cov = np.asarray(measured_cov, dtype=float)
    k, d = measured.shape
    if k == 0:
        return [ScanHypothesis(0.0, np.zeros(0, dtype=int), np.zeros(0))]
    pair_cost = np.full((k, candidate_count), np.inf)
    distances = np.full((k, candidate_count), np.nan)
    if candidate_count:
        predicted, blocks = predictor.individual(np.arange(candidate_count))
        innovation_cov = blocks[None, :, :, :] + measured_cov[:, None, :, :]  # (k, m, d, d)
        innovation = measured[:, None, :] - predicted[None, :, :]  # (k, m, d)
        solved = np.linalg.solve(innovation_cov, innovation[..., None])[..., 0]
        distances = np.einsum("kmi,kmi->km", innovation, solved)
        _, log_det = np.linalg.slogdet(2.0 * np.pi * innovation_cov)
        inside = distances < chi2_gate(d, gate_probability)
        pair_cost[inside] = 0.5 * (distances[inside] + log_det[inside])
    detection_term = np.zeros(candidate_count)  # what pairing landmark i adds to log L beyond N
    missed_total = 0.0  # log L of every landmark in view left unpaired
    if candidate_count and detection is not None:
        probability, visible = detection(predicted)
        missed = np.log1p(-np.asarray(probability, dtype=float))
        visible = np.asarray(visible, dtype=bool)
        missed_total = float(missed[visible].sum())
        detection_term = np.log(probability) - np.where(visible, missed, 0.0)
        pair_cost = pair_cost - detection_term[None, :]
    new_cost = np.full((k, k), np.inf)
    np.fill_diagonal(new_cost, -float(new_landmark_log_density))
    cost = np.hstack([pair_cost, new_cost])
    assignments = _murty(cost, max(1, count) * MURTY_OVERSAMPLING)
    # one joint prediction of every landmark some hypothesis pairs: each hypothesis's joint
    # covariance is a submatrix of it
    union = np.unique(
        np.concatenate([columns[columns < candidate_count] for columns in assignments])
    )
    joint_predicted, joint_cov = (
        predictor.joint(union) if union.size else (np.zeros((0, d)), np.zeros((0, 0)))
    )
    position = {int(landmark): index for index, landmark in enumerate(union)}
    hypotheses = []
    for columns in assignments:
        candidates = np.where(columns < candidate_count, columns, -1)
        paired = np.flatnonzero(candidates >= 0)
        nis = np.full(k, np.nan)
        nis[paired] = distances[paired, candidates[paired]]
        local = np.array([position[int(c)] for c in candidates[paired]], dtype=int)
        rows = (local[:, None] * d + np.arange(d)).ravel()
        score = _joint_log_likelihood(
            measured[paired] - joint_predicted[local],
            joint_cov[rows[:, None], rows],
            measured_cov[paired],
        )
        score += (k - paired.size) * float(new_landmark_log_density)
        score += missed_total + detection_term[candidates[paired]].sum()
        hypotheses.append(ScanHypothesis(score, candidates, nis))
    hypotheses.sort(key=lambda hypothesis: -hypothesis.log_likelihood)
    return hypotheses[: max(1, count)]


def _joint_log_likelihood(
    innovations: np.ndarray, predicted_cov: np.ndarray, measured_cov: np.ndarray
) -> float:
    """``log N(nu; 0, S)`` of p paired sightings' stacked innovation ``nu`` ((p, d) rows),
    ``S = H P H^T`` (p*d, p*d) plus their own covariances (p, d, d); 0 when p = 0."""
    p, d = innovations.shape
    if p == 0:
        return 0.0
    covariance = np.array(predicted_cov, dtype=float)
    diagonal = np.arange(p)
    covariance.reshape(p, d, p, d)[diagonal, :, diagonal, :] += measured_cov
    innovation = innovations.ravel()
    # LAPACK directly: these matrices are small and scipy's wrappers cost more than the work
    lower, failed = dpotrf(covariance, lower=1, clean=1)
    if failed:
        raise np.linalg.LinAlgError("joint innovation covariance is not positive definite")
    whitened, _ = dtrtrs(lower, innovation, lower=1)
    log_det = 2.0 * np.sum(np.log(np.diag(lower)))
    mahalanobis = float(whitened @ whitened)
    return -0.5 * (mahalanobis + log_det + innovation.size * np.log(2.0 * np.pi))


def _murty(cost: np.ndarray, count: int) -> list[np.ndarray]:
    """Up to ``count`` assignments of every row to a distinct column, by increasing total
    ``cost`` (inf: forbidden) (Murty 1968): each found assignment's remaining space is
    partitioned into subproblems that fix its first rows and forbid its next pair.

    A subproblem is the mask of the pairs it allows; every solve replaces the pairs it does
    not allow by one ``big`` cost, larger than any difference of feasible totals, so a
    solution using one is infeasible."""
    rows = cost.shape[0]
    allowed = np.isfinite(cost)
    big = 1.0 + 2.0 * float(np.abs(cost[allowed]).sum())
    first = _solve(cost, allowed, big)
    if first is None:
        return []
    counter = 0
    queue: list[tuple[float, int, np.ndarray, np.ndarray]] = [
        (first[0], counter, first[1], allowed)
    ]
    found: list[np.ndarray] = []
    while queue and len(found) < count:
        _, _, columns, constrained = heapq.heappop(queue)
        found.append(columns)
        fixed = constrained.copy()
        for row in range(rows):
            column = columns[row]
            if np.count_nonzero(fixed[row]) > 1:
                sub = fixed.copy()
                sub[row, column] = False
                solution = _solve(cost, sub, big)
                if solution is not None:
                    counter += 1
                    heapq.heappush(queue, (solution[0], counter, solution[1], sub))
            # the following subproblems keep this row's pair
            fixed[row, :] = False
            fixed[:, column] = False
            fixed[row, column] = True
    return found


def _solve(cost: np.ndarray, allowed: np.ndarray, big: float) -> tuple[float, np.ndarray] | None:
    """The least-cost assignment of every row to an ``allowed`` pair (total, columns), or
    None if there is none (``_murty`` says what ``big`` is)."""
    rows, columns = linear_sum_assignment(np.where(allowed, cost, big))
    if not allowed[rows, columns].all():
        return None
    return float(cost[rows, columns].sum()), columns
