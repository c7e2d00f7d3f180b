"""Data association: individual compatibility gating and JCBB (Neira and Tardos, 2001).

Shared by every estimator (the sensor-based filter, the Aghili filter, EKF-SLAM, the GTSAM
smoothers and loop closing), so it speaks only in *predicted measurements*: each caller
supplies

- ``measured`` ``z_j`` (k, d) with covariance ``R`` (per measurement blocks (k, d, d), or the
  full (k*d, k*d) matrix),
- ``predicted`` ``h_i`` (m, d), the map landmarks as the sensor would see them, with the
  *joint* covariance ``H P H^T`` of all predictions (m*d, m*d): the off-diagonal blocks are
  what makes the joint compatibility test differ from the individual one,
- optionally the cross covariance ``cov(z, h)`` (k*d, m*d), zero for an ordinary scan
  (independent sensor noise); loop closing, where both sides are state landmarks, needs it.

The innovation of pairing measurement ``j`` with landmark ``i`` is ``nu = z_j - h_i`` with
covariance ``R_jj + P_ii - C_ji - C_ji^T``; a hypothesis stacks its pairs, and its joint
Mahalanobis distance ``D^2 = nu^T S^-1 nu`` is compared with the chi-square quantile of
``d * pairs`` degrees of freedom (Neira and Tardos 2001, eqs. (8)-(10)).

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
size) rather than refactored. (The triangular solves use ``numpy.linalg.solve``: on this
machine scipy's ``solve_triangular`` costs milliseconds per tiny call, numpy microseconds.)

Imports numpy, scipy and ``datasets.errors`` only: nothing else from ``filters``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.stats import chi2

from datasets.errors import InputError

DEFAULT_MAX_NODES = 20_000
"""Default cap on joint-compatibility tests per call (see ``benchmarks/bench_association.py``)."""


@lru_cache(maxsize=1024)
def chi2_gate(dof: int, probability: float) -> float:
    """Chi-square quantile: the gate ``D^2 < chi2_gate(dof, probability)`` (dimensionless)."""
    if dof <= 0:
        return 0.0
    return float(chi2.ppf(probability, dof))


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


def _as_blocks(cov: np.ndarray, count: int, d: int, name: str) -> np.ndarray:
    """Per-item (count, d, d) diagonal blocks of a (count, d, d) or (count*d, count*d) input."""
    cov = np.asarray(cov, dtype=float)
    if cov.shape == (count, d, d):
        return cov
    if cov.shape == (count * d, count * d):
        idx = np.arange(count)[:, None] * d + np.arange(d)[None, :]
        return cov[idx[:, :, None], idx[:, None, :]]
    raise InputError(
        f"association: {name} must have shape ({count}, {d}, {d}) or ({count * d}, {count * d}), got {cov.shape}"
    )


def _full_from(cov: np.ndarray, count: int, d: int) -> np.ndarray:
    """Full (count*d, count*d) matrix from blocks or a full matrix."""
    cov = np.asarray(cov, dtype=float)
    if cov.shape == (count * d, count * d):
        return cov
    full = np.zeros((count * d, count * d))
    for j in range(count):
        full[j * d : (j + 1) * d, j * d : (j + 1) * d] = cov[j]
    return full


def _check_inputs(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    predicted: np.ndarray,
    predicted_cov: np.ndarray,
    cross_cov: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, int, int, int]:
    measured = np.asarray(measured, dtype=float)
    predicted = np.asarray(predicted, dtype=float)
    if measured.ndim != 2 or predicted.ndim != 2:
        raise InputError(
            f"association: measured (k, d) and predicted (m, d) must be 2-D, got {measured.shape} and {predicted.shape}"
        )
    k, d = measured.shape
    m = predicted.shape[0]
    if m and predicted.shape[1] != d:
        raise InputError(
            f"association: measured has dimension {d} but predicted has {predicted.shape[1]}"
        )
    for name, array in (
        ("measured", measured),
        ("predicted", predicted),
        ("measured_cov", measured_cov),
        ("predicted_cov", predicted_cov),
    ):
        if not np.all(np.isfinite(np.asarray(array, dtype=float))):
            raise InputError(f"association: {name} contains NaN or inf")
    if cross_cov is not None and np.asarray(cross_cov).shape != (k * d, m * d):
        raise InputError(
            f"association: cross_cov must have shape ({k * d}, {m * d}), got {np.asarray(cross_cov).shape}"
        )
    return measured, predicted, k, m, d


def individual_compatibility(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    predicted: np.ndarray,
    predicted_cov: np.ndarray,
    cross_cov: np.ndarray | None = None,
) -> np.ndarray:
    """Squared Mahalanobis distance of every (measurement, landmark) pair.

    Neira and Tardos (2001), eq. (8): ``D2[j, i] = nu^T S^-1 nu`` with ``nu = z_j - h_i`` and
    ``S = R_jj + P_ii - C_ji - C_ji^T``.

    Args:
        measured: (k, d). measured_cov: (k, d, d) or (k*d, k*d).
        predicted: (m, d). predicted_cov: (m, d, d) blocks or the joint (m*d, m*d).
        cross_cov: cov(z, h), (k*d, m*d), or None (independent).

    Returns:
        (k, m) array of ``D^2`` (d degrees of freedom); ``inf`` where ``S`` is singular.
    """
    measured, predicted, k, m, d = _check_inputs(
        measured, measured_cov, predicted, predicted_cov, cross_cov
    )
    if k == 0 or m == 0:
        return np.zeros((k, m))
    r_blocks = _as_blocks(measured_cov, k, d, "measured_cov")
    p_blocks = _as_blocks(predicted_cov, m, d, "predicted_cov")
    s = r_blocks[:, None, :, :] + p_blocks[None, :, :, :]
    if cross_cov is not None:
        c = np.asarray(cross_cov, dtype=float).reshape(k, d, m, d).transpose(0, 2, 1, 3)
        s = s - c - np.swapaxes(c, -1, -2)
    nu = measured[:, None, :] - predicted[None, :, :]
    distances = np.full((k, m), np.inf)
    try:
        solved = np.linalg.solve(s, nu[..., None])[..., 0]
        distances = np.einsum("kmi,kmi->km", nu, solved)
    except np.linalg.LinAlgError:
        # A singular block somewhere: fall back pair by pair so only that pair is rejected.
        for j in range(k):
            for i in range(m):
                try:
                    distances[j, i] = float(nu[j, i] @ np.linalg.solve(s[j, i], nu[j, i]))
                except np.linalg.LinAlgError:
                    distances[j, i] = np.inf
    distances = np.where(np.isfinite(distances) & (distances >= 0), distances, np.inf)
    return distances


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
    gate_probability: float = 0.99,
    max_nodes: int = DEFAULT_MAX_NODES,
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
    measured, predicted, k, m, d = _check_inputs(
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
        _full_from(measured_cov, k, d),
        _full_from(predicted_cov, m, d),
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
    gate_probability: float = 0.99,
) -> AssociationResult:
    """Individually gated nearest neighbour, each landmark used at most once (greedy by D^2).

    The baseline JCBB improves on; same arguments and result as ``associate_jcbb``
    (``joint_nis`` here is the sum of the individual distances, ``nodes`` 0).
    """
    measured, predicted, k, m, d = _check_inputs(
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
