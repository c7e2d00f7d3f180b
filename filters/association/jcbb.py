"""Joint Compatibility Branch and Bound (Neira and Tardos 2001, section IV) and the gated
nearest-neighbour baseline it improves on.

A hypothesis stacks its pairs, and its joint Mahalanobis distance ``D^2 = nu^T S^-1 nu`` is
compared with the chi-square quantile of ``d * pairs`` degrees of freedom (Neira and Tardos
2001, eqs. (8)-(10)).

Bounded run time (both mechanisms, always on):

1. *pre-gating*: only individually compatible pairs (chi-square gate, ``d`` dof) enter the
   interpretation tree, so its branching factor is the number of gated candidates, not m;
2. *a cap on interpretation-tree nodes* (``max_nodes``, each node = one joint-compatibility
   test): when reached, the search stops and returns the best hypothesis found so far, and
   ``AssociationResult.truncated`` says so. Measurements are ordered fewest-candidates first
   and candidates nearest first, so the first leaf reached is the greedy nearest-neighbour
   hypothesis filtered by joint compatibility and a truncated search is still a jointly
   compatible answer.

Joint distances are computed incrementally: the Cholesky factor of the hypothesis
covariance is extended by one ``d x d`` block per node (O(n^2 d) per node, n the hypothesis
size) rather than refactored. (The triangular solves use ``numpy.linalg.solve``: with BLAS
threads contending, scipy's ``solve_triangular`` was measured at milliseconds per tiny
call, numpy at microseconds.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError
from datasets.estimator_options import DEFAULT_GATE_PROBABILITY, DEFAULT_MAX_JCBB_NODES
from filters.association.compatibility import (
    check_inputs,
    chi2_gate,
    full_from,
    individual_compatibility,
)


@dataclass(frozen=True)
class AssociationResult:
    """The outcome of one association call.

    Attributes:
        assignments: map index for each measurement, shape (k,), ``-1`` when unassigned.
        individual_nis: ``D^2`` of each assigned pair on its own (d dof), shape (k,), NaN
            when unassigned.
        candidate_counts: individually compatible map landmarks per measurement, shape (k,).
            An unassigned measurement with candidates is *ambiguous* (callers should
            neither update with it nor start a new landmark from it); one with none is new.
        joint_nis: ``D^2`` of the chosen hypothesis (``pairs * d`` dof), 0 when empty.
        pairs: number of assigned measurements.
        nodes: joint-compatibility tests performed (interpretation-tree nodes visited).
        truncated: True when the node cap stopped the search early.
        dimension: d, the dimension of one measurement.
    """

    assignments: np.ndarray
    individual_nis: np.ndarray
    candidate_counts: np.ndarray
    joint_nis: float
    pairs: int
    nodes: int
    truncated: bool
    dimension: int

    @property
    def dof(self) -> int:
        """Degrees of freedom of ``joint_nis``."""
        return int(self.pairs * self.dimension)

    @property
    def ambiguous(self) -> np.ndarray:
        """(k,) bool: unassigned although individually compatible with some landmark."""
        return (self.assignments < 0) & (self.candidate_counts > 0)


class _JointSearch:
    """Depth-first interpretation-tree search with an incremental Cholesky factor."""

    def __init__(
        self,
        measured: np.ndarray,
        predicted: np.ndarray,
        r_full: np.ndarray,
        p_full: np.ndarray,
        c_full: np.ndarray | None,
        order: list[int],
        candidates: list[list[int]],
        gate_probability: float,
        max_nodes: int,
    ) -> None:
        self.z = measured
        self.h = predicted
        self.r = r_full
        self.p = p_full
        self.c = c_full
        self.d = measured.shape[1]
        self.order = order
        self.candidates = candidates
        self.probability = gate_probability
        self.max_nodes = max_nodes
        self.nodes = 0
        self.truncated = False
        self.best: list[tuple[int, int]] = []
        self.best_d2 = 0.0
        # Remaining measurements with at least one candidate after position ``level``.
        self.remaining = [len(order) - level for level in range(len(order) + 1)]
        self.offsets = np.arange(self.d)

    def _rows(self, j: int, i: int) -> tuple[np.ndarray, np.ndarray]:
        return j * self.d + self.offsets, i * self.d + self.offsets

    def _cross(
        self, zrows: np.ndarray, hrows: np.ndarray, zr: np.ndarray, hr: np.ndarray
    ) -> np.ndarray:
        """cov(nu_H, nu_new) for the stacked hypothesis rows: R + P - C_zh - C_hz."""
        block = self.r[np.ix_(zrows, zr)] + self.p[np.ix_(hrows, hr)]
        if self.c is not None:
            block = block - self.c[np.ix_(zrows, hr)] - self.c[np.ix_(zr, hrows)].T
        return block

    def run(self) -> None:
        empty = np.zeros(0, dtype=int)
        self._descend(0, [], empty, empty, np.zeros((0, 0)), np.zeros(0), 0.0, set())

    def _descend(
        self,
        level: int,
        pairs: list[tuple[int, int]],
        zrows: np.ndarray,
        hrows: np.ndarray,
        chol: np.ndarray,
        whitened: np.ndarray,
        d2: float,
        used: set[int],
    ) -> None:
        if level == len(self.order):
            if len(pairs) > len(self.best) or (len(pairs) == len(self.best) and d2 < self.best_d2):
                self.best = list(pairs)
                self.best_d2 = d2
            return
        j = self.order[level]
        for i in self.candidates[j]:
            if self.truncated:
                return
            if i in used:
                continue
            # Bound: even pairing every remaining measurement cannot beat the best.
            if len(pairs) + self.remaining[level] < len(self.best):
                break
            if self.nodes >= self.max_nodes:
                self.truncated = True
                return
            self.nodes += 1
            zr, hr = self._rows(j, i)
            cross = self._cross(zrows, hrows, zr, hr)
            block = self._cross(zr, hr, zr, hr)
            try:
                l21 = np.linalg.solve(chol, cross).T if pairs else np.zeros((self.d, 0))
                l22 = np.linalg.cholesky(block - l21 @ l21.T)
            except np.linalg.LinAlgError:
                continue
            nu = self.z[j] - self.h[i]
            b2 = np.linalg.solve(l22, nu - l21 @ whitened)
            new_d2 = d2 + float(b2 @ b2)
            if new_d2 >= chi2_gate(self.d * (len(pairs) + 1), self.probability):
                continue
            n = chol.shape[0]
            new_chol = np.zeros((n + self.d, n + self.d))
            new_chol[:n, :n] = chol
            new_chol[n:, :n] = l21
            new_chol[n:, n:] = l22
            used.add(i)
            pairs.append((j, i))
            self._descend(
                level + 1,
                pairs,
                np.concatenate([zrows, zr]),
                np.concatenate([hrows, hr]),
                new_chol,
                np.concatenate([whitened, b2]),
                new_d2,
                used,
            )
            pairs.pop()
            used.discard(i)
        if self.truncated:
            return
        # The star branch (measurement j unpaired), only if it can still beat the best.
        if len(pairs) + self.remaining[level + 1] > len(self.best):
            self._descend(level + 1, pairs, zrows, hrows, chol, whitened, d2, used)


def associate_jcbb(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    predicted: np.ndarray,
    predicted_cov: np.ndarray,
    cross_cov: np.ndarray | None = None,
    gate_probability: float = DEFAULT_GATE_PROBABILITY,
    max_nodes: int = DEFAULT_MAX_JCBB_NODES,
    candidate_mask: np.ndarray | None = None,
) -> AssociationResult:
    """Joint Compatibility Branch and Bound (Neira and Tardos 2001, section IV).

    Finds the hypothesis with the most pairings whose stacked innovation passes the joint
    chi-square test; among equally large ones the smallest joint ``D^2``. Each landmark
    pairs with at most one measurement.

    Args:
        measured: (k, d) measurements in the sensor frame.
        measured_cov: (k, d, d) per-measurement covariances or the full (k*d, k*d).
        predicted: (m, d) predicted measurements of the map landmarks.
        predicted_cov: joint covariance of the predictions ``H P H^T``, (m*d, m*d); per
            landmark blocks (m, d, d) are accepted and mean "uncorrelated" (then JCBB
            reduces to individually gated, mutually exclusive nearest pairing).
        cross_cov: cov(z, h) (k*d, m*d) or None for independent sensor noise.
        gate_probability: probability of the chi-square gates (individual and joint).
        max_nodes: cap on joint-compatibility tests (bounded run time).
        candidate_mask: optional (k, m) bool: pairs allowed at all (e.g. landmarks in view).

    Returns:
        ``AssociationResult``.
    """
    measured, predicted, k, m, d = check_inputs(
        measured, measured_cov, predicted, predicted_cov, cross_cov
    )
    if max_nodes < 1:
        raise InputError(f"association: max_nodes must be >= 1, got {max_nodes}")
    if not 0.0 < gate_probability < 1.0:
        raise InputError(f"association: gate_probability must be in (0, 1), got {gate_probability}")
    empty = AssociationResult(
        assignments=np.full(k, -1, dtype=int),
        individual_nis=np.full(k, np.nan),
        candidate_counts=np.zeros(k, dtype=int),
        joint_nis=0.0,
        pairs=0,
        nodes=0,
        truncated=False,
        dimension=d,
    )
    if k == 0 or m == 0:
        return empty
    distances = individual_compatibility(
        measured, measured_cov, predicted, predicted_cov, cross_cov
    )
    gated = distances < chi2_gate(d, gate_probability)
    if candidate_mask is not None:
        mask = np.asarray(candidate_mask, dtype=bool)
        if mask.shape != (k, m):
            raise InputError(
                f"association: candidate_mask must have shape ({k}, {m}), got {mask.shape}"
            )
        gated &= mask
    counts = gated.sum(axis=1).astype(int)
    candidates = [
        list(np.flatnonzero(gated[j])[np.argsort(distances[j, gated[j]])]) for j in range(k)
    ]
    # Fewest candidates first: unambiguous pairs fix the hypothesis early and prune more.
    order = sorted((j for j in range(k) if counts[j] > 0), key=lambda j: (counts[j], j))
    if not order:
        return AssociationResult(
            empty.assignments, empty.individual_nis, counts, 0.0, 0, 0, False, d
        )
    search = _JointSearch(
        measured,
        predicted,
        full_from(measured_cov, k, d),
        full_from(predicted_cov, m, d),
        None if cross_cov is None else np.asarray(cross_cov, dtype=float),
        order,
        candidates,
        gate_probability,
        int(max_nodes),
    )
    search.run()
    assignments = np.full(k, -1, dtype=int)
    individual = np.full(k, np.nan)
    for j, i in search.best:
        assignments[j] = i
        individual[j] = distances[j, i]
    return AssociationResult(
        assignments=assignments,
        individual_nis=individual,
        candidate_counts=counts,
        joint_nis=float(search.best_d2),
        pairs=len(search.best),
        nodes=search.nodes,
        truncated=search.truncated,
        dimension=d,
    )


def associate_nearest_neighbour(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    predicted: np.ndarray,
    predicted_cov: np.ndarray,
    cross_cov: np.ndarray | None = None,
    gate_probability: float = DEFAULT_GATE_PROBABILITY,
) -> AssociationResult:
    """Individually gated nearest neighbour, each landmark used at most once (greedy by D^2).

    The baseline JCBB improves on; same arguments and result as ``associate_jcbb``
    (``joint_nis`` here is the sum of the individual distances, ``nodes`` 0).
    """
    measured, predicted, k, m, d = check_inputs(
        measured, measured_cov, predicted, predicted_cov, cross_cov
    )
    assignments = np.full(k, -1, dtype=int)
    individual = np.full(k, np.nan)
    if k == 0 or m == 0:
        return AssociationResult(
            assignments, individual, np.zeros(k, dtype=int), 0.0, 0, 0, False, d
        )
    distances = individual_compatibility(
        measured, measured_cov, predicted, predicted_cov, cross_cov
    )
    gated = distances < chi2_gate(d, gate_probability)
    counts = gated.sum(axis=1).astype(int)
    used: set[int] = set()
    for flat in np.argsort(np.where(gated, distances, np.inf), axis=None):
        j, i = divmod(int(flat), m)
        if not gated[j, i]:
            break
        if assignments[j] >= 0 or i in used:
            continue
        assignments[j] = i
        individual[j] = distances[j, i]
        used.add(i)
    pairs = int((assignments >= 0).sum())
    return AssociationResult(
        assignments, individual, counts, float(np.nansum(individual)), pairs, 0, False, d
    )
