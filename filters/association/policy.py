"""The association policy every estimator uses: one decision per sighting, typed, with
the reason for every sighting that is not used.

An estimator supplies its *candidates* (the map landmarks it could pair a sighting with,
each with the source id it was created from, when scans carry ids) and a ``Predictor``
that gives their predicted measurements and covariances ``H P H^T``; the policy decides,
by the scan's ids or geometrically (JCBB or gated nearest neighbour), and returns a
``ScanAssociation``: for each sighting a ``Decision`` (matched / new / rejected /
ambiguous), the candidate it matched, and why a sighting was not used. Estimators record
every decision (``datasets.estimate.EstimateRecorder.association``), so no estimator can
drop a sighting silently, and a comparison never depends on who wrote which gate.

Geometric association (Neira and Tardos 2001): candidates individually compatible with
some sighting at ``gate_probability`` enter JCBB with their *joint* predicted covariance;
a sighting left unpaired starts a new landmark only when it lies outside every candidate's
gate at the looser ``new_landmark_probability`` (at the association gate, 1 % of true
sightings fall outside their own landmark's gate and would otherwise become duplicates);
between the two gates it pairs by mutual exclusion when exactly one landmark is in reach and
no other sighting reaches it (``_exclusive_wide_pairs``), used with its noise inflated so
that its NIS equals the association gate (as a known id outside the id gate is, below), and
is otherwise *ambiguous*: neither used nor mapped.

With ids: a sighting pairs with the candidate created from the same id, and the same id
twice in one scan keeps its first sighting. A known id whose sighting falls outside the
``id_gate_probability`` chi-square gate (``D^2 > g``) is used with its noise *inflated* so
that its NIS equals the gate: ``R' = R + (c - 1) S`` with ``c = D^2 / g`` and
``S = H P H^T + R`` its innovation covariance, so ``S' = c S`` and the gain is ``K / c``
(counted in ``inflation``). Why not reject it: the association is known, so a large
innovation says the prediction is off by more than its covariance admits, and rejecting
such sightings keeps an overconfident filter blind for good (Victoria Park, with the file's
optimistic odometry: 2725 of 3640 sightings rejected and the trajectory left on dead
reckoning). Why not re-initialise the landmark: when it is the vehicle that drifted, that
throws away the map's information and corrupts it. Inflating is the Huber-type step of a
robust M-estimator: a wrong pose is pulled back over a few scans, while a single bad
sighting (a wrong id) moves the state by no more than a sighting at the gate would.

Sightings whose errors are correlated in time (``datasets.sighting_correlation``, where the
sequence states a model): ``decorrelated`` inflates the noise of each matched sighting for
the time since the previous sighting of the same landmark, so that a burst of sightings
counts as the information it carries, not as that many independent measurements. Gating
and the recorded NIS use the sighting's own noise; the update uses the inflated one.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, replace
from typing import Literal, Protocol

import numpy as np

from datasets.errors import InputError
from datasets.estimate import AssociationDecision
from datasets.estimator_options import AssociationOptions
from datasets.sighting_correlation import SightingCorrelation
from filters.association.compatibility import chi2_gate, individual_compatibility
from filters.association.jcbb import (
    AssociationResult,
    associate_jcbb,
    associate_nearest_neighbour,
)

Decision = AssociationDecision
"""The decision vocabulary lives in ``datasets`` (it crosses into the metrics)."""


class Reason(enum.StrEnum):
    """Why a sighting was not used (the shared ones; estimators may add their own text)."""

    SINGULAR = "singular innovation covariance"
    REPEATED_ID = "id repeated in the scan"
    NOT_IN_HYPOTHESIS = "compatible, but not in the jointly compatible hypothesis"
    BETWEEN_GATES = "outside the association gate, inside the new-landmark gate"
    NOT_FINITE = "non-finite point or covariance"
    DUPLICATE_SIGHTING = "compatible with another new sighting of the same scan"


Mode = Literal["ids", "jcbb", "nearest", "multi-hypothesis"]


class Predictor(Protocol):
    """Predicted measurements of candidate landmarks, from the estimator's current belief."""

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(predicted (n, d), marginal predicted covariances ``H_i P H_i^T`` (n, d, d))."""

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(predicted (n, d), joint predicted covariance ``H P H^T`` (n d, n d))."""


@dataclass(frozen=True)
class ScanAssociation:
    """The decisions for one scan's sightings.

    Attributes:
        mode: how it was decided (``ids``, ``jcbb``, ``nearest``, or ``multi-hypothesis``:
            one of ``hypotheses.ranked_hypotheses``).
        decisions: one ``Decision`` per sighting, length k.
        candidates: the matched candidate's index per sighting, shape (k,), -1 unless matched.
        reasons: why each sighting was not used ("" for matched and new), length k.
        individual_nis: ``D^2`` of each matched pair on its own (d dof), shape (k,), NaN
            otherwise.
        noise: the covariance to use each sighting with, shape (k, d, d): its own, inflated
            where it fell outside the id gate (module docstring).
        inflation: ``c`` of each sighting, shape (k,): 1 unless inflated.
        search: the JCBB / nearest-neighbour result (nodes, truncation), None with ids.
        alternatives: for a geometric decision, how many *other* interpretations each
            sighting had within the new-landmark gate, shape (k,): the candidates there
            besides the one it matched, and for a pairing outside the association gate
            (``_exclusive_wide_pairs``) also "a new landmark"; 0 where the decision was
            the only one in reach; None when not judged (ids, or a hypothesis of
            ``ekf-slam-mht``, which keeps the alternatives instead of choosing).
    """

    mode: Mode
    decisions: tuple[Decision, ...]
    candidates: np.ndarray
    reasons: tuple[str, ...]
    individual_nis: np.ndarray
    noise: np.ndarray
    inflation: np.ndarray
    search: AssociationResult | None = None
    alternatives: np.ndarray | None = None

    def alternatives_of(self, j: int) -> int:
        """Sighting ``j``'s other interpretations (``alternatives``), -1 when not judged."""
        return -1 if self.alternatives is None else int(self.alternatives[j])

    def rows(self, decision: Decision) -> np.ndarray:
        """Indices of the sightings with ``decision``, increasing."""
        return np.array([j for j, d in enumerate(self.decisions) if d == decision], dtype=int)

    def count(self, decision: Decision) -> int:
        return sum(1 for d in self.decisions if d == decision)

    def overrule(
        self, rows: np.ndarray | list[int], decision: Decision, reason: str
    ) -> ScanAssociation:
        """The same association with ``rows`` re-decided (an estimator's own constraint,
        e.g. no new landmark before the map is anchored), the reason kept."""
        decisions = list(self.decisions)
        reasons = list(self.reasons)
        candidates = self.candidates.copy()
        nis = self.individual_nis.copy()
        for j in rows:
            decisions[int(j)] = decision
            reasons[int(j)] = reason
            if decision != Decision.MATCHED:
                candidates[int(j)] = -1
                nis[int(j)] = np.nan
        return replace(
            self,
            decisions=tuple(decisions),
            reasons=tuple(reasons),
            candidates=candidates,
            individual_nis=nis,
        )

    def relabelled(self, labels: np.ndarray) -> ScanAssociation:
        """The same decisions with every matched candidate index ``i`` replaced by
        ``labels[i]`` (e.g. from a subset's index to the map id)."""
        candidates = self.candidates.copy()
        matched = candidates >= 0
        candidates[matched] = np.asarray(labels, dtype=int)[candidates[matched]]
        return replace(self, candidates=candidates)

    def embedded(self, rows: np.ndarray, total: int, reason: str) -> ScanAssociation:
        """The association of a whole scan of ``total`` sightings of which this one decided
        ``rows``; the others are rejected with ``reason`` (e.g. non-finite points)."""
        rows = np.asarray(rows, dtype=int)
        if len(rows) == total:
            return self
        decisions = [Decision.REJECTED] * total
        reasons = [str(reason)] * total
        candidates = np.full(total, -1, dtype=int)
        nis = np.full(total, np.nan)
        d = self.noise.shape[-1] if self.noise.ndim == 3 else 0
        noise = np.full((total, d, d), np.nan)
        inflation = np.ones(total)
        alternatives = None if self.alternatives is None else np.full(total, -1, dtype=int)
        for local, j in enumerate(rows):
            decisions[j], reasons[j] = self.decisions[local], self.reasons[local]
            candidates[j], nis[j] = self.candidates[local], self.individual_nis[local]
            noise[j], inflation[j] = self.noise[local], self.inflation[local]
            if alternatives is not None:
                alternatives[j] = self.alternatives[local]
        return replace(
            self,
            decisions=tuple(decisions),
            candidates=candidates,
            reasons=tuple(reasons),
            individual_nis=nis,
            noise=noise,
            inflation=inflation,
            alternatives=alternatives,
        )


def _exclusive_wide_pairs(
    distances: np.ndarray, wide_gate: float, reasons: list[str], candidates: np.ndarray
) -> list[tuple[int, int]]:
    """Sightings left between the gates that pair by mutual exclusion: sighting j, outside
    every candidate's association gate, has exactly one candidate i inside the new-landmark
    gate, no other sighting of the scan has i inside that gate, and i is not matched yet.

    Why: a true sighting falls outside its own landmark's association gate with the gate's
    complement probability (1 % at 0.99), and left there it is neither used nor mapped.
    On ``sim:guerreiro-loop --data ids=false`` (sensor-based, seed 0) that was 155 of 19627
    sightings, all of them true, which capped the recall at 0.989. With one landmark only in
    reach and no rival sighting, the pairing is what the new-landmark gate already assumes
    when it refuses to start a landmark there.

    A sighting JCBB left out although it was inside some association gate is not paired
    here: the joint test rejected it.

    Why inflated: on real data the premise fails more often than not. On UTIAS dataset 1
    without ids (ekf-slam), 14-64 % of these pairings on robots 1-4 were with the landmark a
    sighting of the same barcode had created (91 % on robot 5; JCBB's own pairings 64-92 %),
    and the first wrong pairing of a run was often one of them: a sighting of a landmark
    not yet mapped, seen after a long gap by a robot whose heading had drifted, with a
    mapped one 3 m away alone in reach. Used at full weight it pulled the heading by 46 deg
    (robot 4 at 91.6 s) and every later sighting of that landmark followed. Used as a
    sighting at the association gate, it moves the state no more than a sighting JCBB
    accepts; on the simulator, where all of them are true, recall and NIS are unchanged
    (``sim:guerreiro-loop --data ids=false``, seeds 0-9).

    Args: distances (k, m) individual D^2; wide_gate the new-landmark gate; reasons (k,)
    and candidates (k,) as decided so far. Returns (j, i) pairs."""
    inside = distances < wide_gate
    claimed = {int(i) for i in candidates if i >= 0}
    pairs = []
    for j, reason in enumerate(reasons):
        if reason != Reason.BETWEEN_GATES.value:
            continue
        (reach,) = np.nonzero(inside[j])
        if reach.size != 1 or int(reach[0]) in claimed:
            continue
        if np.count_nonzero(inside[:, reach[0]]) == 1:
            pairs.append((j, int(reach[0])))
    return pairs


def _alternatives(
    distances: np.ndarray, candidates: np.ndarray, inflation: np.ndarray, wide_gate: float
) -> np.ndarray:
    """(k,) the other interpretations each sighting had within the new-landmark gate
    ``wide_gate`` (``ScanAssociation.alternatives``): every candidate in reach (``distances``
    (k, m) individual D^2) but the one it matched, and "new landmark" for a pairing made
    outside the association gate (its inflation > 1)."""
    reach = distances < wide_gate
    counts = reach.sum(axis=1)
    matched = candidates >= 0
    counts[matched] -= reach[np.flatnonzero(matched), candidates[matched]]
    return counts + (matched & (inflation > 1.0))


def _inflated_to_gate(
    distance: float, gate: float, measured_cov: np.ndarray, predicted_cov: np.ndarray
) -> tuple[float, np.ndarray]:
    """A sighting at ``D^2 = distance`` beyond ``gate`` used as one at the gate (module
    docstring): the factor ``c = D^2 / gate`` and the noise ``R + (c - 1) S`` [(d, d)], with
    ``S = H P H^T + R`` from ``predicted_cov`` (``H P H^T``) and ``measured_cov`` (``R``)."""
    factor = distance / gate
    return factor, measured_cov + (factor - 1.0) * (predicted_cov + measured_cov)


def _empty(mode: Mode, measured_cov: np.ndarray) -> ScanAssociation:
    """Every sighting new, with its own noise."""
    noise = np.array(measured_cov, dtype=float)
    count = len(noise)
    return ScanAssociation(
        mode,
        (Decision.NEW,) * count,
        np.full(count, -1, dtype=int),
        ("",) * count,
        np.full(count, np.nan),
        noise,
        np.ones(count),
    )


class AssociationPolicy:
    """Decides every sighting of a scan (module docstring) under ``AssociationOptions``.

    Args:
        correlation: the sequence's model of sighting errors correlated in time
            (``NoiseSpec.sighting_correlation``), or None (independent sightings).
    """

    def __init__(
        self,
        options: AssociationOptions,
        dimension: int,
        correlation: SightingCorrelation | None = None,
    ) -> None:
        self.options = options
        self.dimension = dimension
        self.correlation = correlation
        self._last_sighting: dict[int, float] = {}

    def branch(self) -> AssociationPolicy:
        """An independent copy (same options; its own record of the latest sightings), for
        an estimator that keeps several hypotheses of its map."""
        copied = AssociationPolicy(self.options, self.dimension, self.correlation)
        copied._last_sighting = dict(self._last_sighting)
        return copied

    # ------------------------------------------------------------------ correlation
    def decorrelated(
        self,
        association: ScanAssociation,
        t: float,
        measured: np.ndarray,
        measured_cov: np.ndarray,
        landmarks: np.ndarray,
    ) -> ScanAssociation:
        """The association with the noise of every matched sighting inflated for the time
        since the previous sighting of its landmark (module docstring; unchanged without a
        correlation model), and ``t`` [s] remembered as that landmark's latest sighting.
        The inflation is that of the sighting's own covariance, added to whatever the id
        gate already added.

        Args:
            measured: (k, d) the sightings. measured_cov: (k, d, d) their own covariances.
            landmarks: (k,) the map id each matched row is paired with (other rows ignored).
        """
        if self.correlation is None:
            return association
        noise = association.noise.copy()
        for j in association.rows(Decision.MATCHED):
            noise[j] = self.correlated_noise(
                int(landmarks[j]), t, measured[j], measured_cov[j], noise[j]
            )
        return replace(association, noise=noise)

    def correlated_noise(
        self,
        landmark: int,
        t: float,
        measured: np.ndarray,
        measured_cov: np.ndarray,
        noise: np.ndarray,
    ) -> np.ndarray:
        """``noise`` (d, d) of one sighting of map id ``landmark`` at ``t`` [s], grown by
        the correlation model's inflation of its own covariance ``measured_cov`` for the
        time since that landmark's previous sighting; ``t`` is remembered as its latest.
        For a sighting matched after ``decorrelated`` ran (e.g. to a landmark created
        from an earlier sighting of the same keyframe). Unchanged without a model."""
        if self.correlation is None:
            return noise
        previous = self._last_sighting.get(landmark)
        self._last_sighting[landmark] = float(t)
        if previous is None:
            return noise
        own = np.asarray(measured_cov, dtype=float)
        return noise + self.correlation.inflate(own, measured, t - previous) - own

    def sighted(self, landmark: int, t: float) -> None:
        """A new landmark ``landmark`` (map id) was created from a sighting at ``t`` [s]: the
        next sighting is correlated with that one."""
        if self.correlation is not None:
            self._last_sighting[int(landmark)] = float(t)

    def mode(self, scan_ids: np.ndarray | None, t: float) -> Mode:
        """``ids`` when the options and the scan allow it, else the geometric method."""
        method = self.options.association
        if method == "ids" and scan_ids is None:
            raise InputError(
                f"association=ids but the landmark scan at t={t:.6f} s has no ids "
                "(use association=jcbb or auto)"
            )
        if method == "auto":
            return "ids" if scan_ids is not None else "jcbb"
        return method

    # ------------------------------------------------------------------ by ids
    def by_ids(
        self,
        scan_ids: np.ndarray,
        measured: np.ndarray,
        measured_cov: np.ndarray,
        candidate_ids: np.ndarray,
        predictor: Predictor,
    ) -> ScanAssociation:
        """Pair each sighting with the candidate of the same source id; gate the pairs.

        Args:
            scan_ids: source id of each sighting (k,).
            measured: (k, d). measured_cov: (k, d, d).
            candidate_ids: source id of each candidate (m,).
            predictor: predictions of the candidates (only the paired ones are asked for,
                and only when there is an id gate); may be None without a gate.
        """
        scan_ids = np.asarray(scan_ids, dtype=int)
        k = len(scan_ids)
        result = _empty("ids", measured_cov)
        decisions, reasons = list(result.decisions), list(result.reasons)
        candidates, noise, inflation = result.candidates, result.noise, result.inflation
        index_of = {
            int(source): index for index, source in enumerate(np.asarray(candidate_ids, int))
        }
        seen: set[int] = set()
        for j, source in enumerate(scan_ids):
            source = int(source)
            if source in seen:
                decisions[j], reasons[j] = Decision.REJECTED, Reason.REPEATED_ID.value
                continue
            seen.add(source)
            if source in index_of:
                decisions[j], candidates[j] = Decision.MATCHED, index_of[source]
        paired = np.array([j for j in range(k) if decisions[j] == Decision.MATCHED], dtype=int)
        nis = np.full(k, np.nan)
        if paired.size and self.options.id_gate_probability is not None:
            predicted, blocks = predictor.individual(candidates[paired])
            own = _pair_distances(measured[paired], measured_cov[paired], predicted, blocks)
            nis[paired] = own
            gate = chi2_gate(self.dimension, self.options.id_gate_probability)
            for local, j in enumerate(paired):
                distance = own[local]
                if not np.isfinite(distance):
                    decisions[j], reasons[j] = Decision.REJECTED, Reason.SINGULAR.value
                    candidates[j], nis[j] = -1, np.nan
                elif distance > gate:
                    inflation[j], noise[j] = _inflated_to_gate(
                        distance, gate, measured_cov[j], blocks[local]
                    )
        return ScanAssociation(
            "ids", tuple(decisions), candidates, tuple(reasons), nis, noise, inflation
        )

    # ------------------------------------------------------------------ geometric
    def by_geometry(
        self,
        measured: np.ndarray,
        measured_cov: np.ndarray,
        candidate_count: int,
        predictor: Predictor,
        mode: Mode = "jcbb",
    ) -> ScanAssociation:
        """JCBB (or gated nearest neighbour) against ``candidate_count`` candidates.

        Args:
            measured: (k, d). measured_cov: (k, d, d).
            candidate_count: m; the predictor answers for indices 0..m-1.
            mode: ``jcbb`` or ``nearest``.
        """
        k, d = np.asarray(measured).shape
        if k == 0 or candidate_count == 0:
            return replace(_empty(mode, measured_cov), alternatives=np.zeros(k, dtype=int))
        predicted, blocks = predictor.individual(np.arange(candidate_count))
        distances = individual_compatibility(measured, measured_cov, predicted, blocks)
        gated = np.flatnonzero(
            (distances < chi2_gate(d, self.options.gate_probability)).any(axis=0)
        )
        near = (distances < chi2_gate(d, self.options.new_landmark_probability)).any(axis=1)
        decisions = [Decision.NEW if not near[j] else Decision.AMBIGUOUS for j in range(k)]
        reasons = ["" if not near[j] else Reason.BETWEEN_GATES.value for j in range(k)]
        candidates = np.full(k, -1, dtype=int)
        nis = np.full(k, np.nan)
        search = None
        if gated.size:
            subset_predicted, subset_joint = predictor.joint(gated)
            if mode == "nearest":
                search = associate_nearest_neighbour(
                    measured,
                    measured_cov,
                    subset_predicted,
                    subset_joint,
                    gate_probability=self.options.gate_probability,
                )
            else:
                search = associate_jcbb(
                    measured,
                    measured_cov,
                    subset_predicted,
                    subset_joint,
                    gate_probability=self.options.gate_probability,
                    max_nodes=self.options.max_jcbb_nodes,
                )
            for j in range(k):
                if search.assignments[j] >= 0:
                    decisions[j], reasons[j] = Decision.MATCHED, ""
                    candidates[j] = gated[search.assignments[j]]
                    nis[j] = search.individual_nis[j]
                elif search.candidate_counts[j] > 0:
                    decisions[j], reasons[j] = Decision.AMBIGUOUS, Reason.NOT_IN_HYPOTHESIS.value
        noise, inflation = np.array(measured_cov, dtype=float), np.ones(k)
        gate = chi2_gate(d, self.options.gate_probability)
        for j, i in _exclusive_wide_pairs(
            distances, chi2_gate(d, self.options.new_landmark_probability), reasons, candidates
        ):
            decisions[j], reasons[j], candidates[j], nis[j] = (
                Decision.MATCHED,
                "",
                i,
                distances[j, i],
            )
            # used as a sighting at the association gate would be (module docstring)
            inflation[j], noise[j] = _inflated_to_gate(
                distances[j, i], gate, measured_cov[j], blocks[i]
            )
        return ScanAssociation(
            mode,
            tuple(decisions),
            candidates,
            tuple(reasons),
            nis,
            noise,
            inflation,
            search,
            _alternatives(
                distances,
                candidates,
                inflation,
                chi2_gate(d, self.options.new_landmark_probability),
            ),
        )

    def distinct_new(
        self, measured: np.ndarray, measured_cov: np.ndarray, association: ScanAssociation
    ) -> ScanAssociation:
        """Reject a new sighting compatible with an earlier new sighting of the same scan
        (a corner detected twice must not become two landmarks)."""
        kept: list[int] = []
        duplicates: list[int] = []
        gate = chi2_gate(self.dimension, self.options.gate_probability)
        for j in association.rows(Decision.NEW):
            for i in kept:
                difference = measured[j] - measured[i]
                if (
                    difference @ np.linalg.solve(measured_cov[j] + measured_cov[i], difference)
                    < gate
                ):
                    duplicates.append(int(j))
                    break
            else:
                kept.append(int(j))
        if not duplicates:
            return association
        return association.overrule(duplicates, Decision.REJECTED, Reason.DUPLICATE_SIGHTING.value)


def _pair_distances(
    measured: np.ndarray, measured_cov: np.ndarray, predicted: np.ndarray, blocks: np.ndarray
) -> np.ndarray:
    """``D^2`` of each sighting with its own prediction (n,)."""
    total = np.asarray(measured_cov, float) + np.asarray(blocks, float)
    innovation = np.asarray(measured, float) - np.asarray(predicted, float)
    try:
        solved = np.linalg.solve(total, innovation[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.full(len(innovation), np.inf)
    return np.einsum("ni,ni->n", innovation, solved)
