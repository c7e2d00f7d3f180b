"""Degradations a run must not hide: said on the screen, written to metrics.json.

- **Data**: rows a loader dropped or repaired (``Sequence.counts``, each count with its
  name), and the warnings a loader states and a pass over the stream adds
  (``Sequence.all_warnings``).
- **Contested association**: without ids, a single hypothesis decides each sighting once;
  where more than ``CONTESTED_WARNING_FRACTION`` of those decisions had another
  interpretation within the new-landmark gate, the run warns (its map may hold pairings
  it cannot revise).
- **Association**: known-id sightings an estimator did not use as stated: rejected
  (repeated, singular, non-finite) or used with its noise inflated to the id gate
  (``filters.association.policy``). Above ``ASSOCIATION_WARNING_FRACTION`` of all known-id
  sightings, a warning names the estimator, the dataset, the fraction, and where it was
  worst: the time of the 10 s window with the most of them. A high inflated fraction says
  the stated noise (odometry, landmarks) is optimistic for that recording.
"""

from __future__ import annotations

import numpy as np

from datasets.estimate import AssociationDecision, Estimate
from datasets.sequence import Sequence

ASSOCIATION_WARNING_FRACTION = 0.05
"""Fraction of known-id sightings rejected or inflated above which a run warns."""

CONTESTED_WARNING_FRACTION = 0.10
"""Fraction of single-hypothesis geometric decisions with another interpretation in reach
above which a run warns (``association_contested_fraction``). Measured with ekf-slam
without ids: ``sim:guerreiro-loop`` seeds 0-9 read 1.4-8.5 % contested at association
precision 0.9996 or better; UTIAS dataset 1 robots 1-5 read 12.9-18.3 % at 0.88-0.99 (the
single hypothesis is right or wrong there by luck, and 0.98 is not guaranteed)."""

WINDOW_S = 10.0


def data_warnings(sequence: Sequence) -> list[str]:
    """One line per non-zero count of dropped or repaired rows, and the loader's warnings."""
    lines = []
    counts = sequence.counts or {}
    dropped = {name: int(value) for name, value in counts.items() if int(value) > 0}
    if dropped:
        listed = ", ".join(f"{name.replace('_', ' ')} {value}" for name, value in dropped.items())
        lines.append(f"{sequence.name}: rows dropped or repaired by the loader: {listed}")
    lines.extend(f"{sequence.name}: {text}" for text in sequence.all_warnings())
    return lines


def contested_warning(estimate: Estimate, sequence: Sequence, estimator: str) -> list[str]:
    """A warning when a single-hypothesis association without ids had another
    interpretation in reach for more than ``CONTESTED_WARNING_FRACTION`` of its decisions."""
    alternatives = np.asarray(estimate.diagnostics.assoc_alternatives)
    judged = alternatives >= 0
    if not judged.any():
        return []
    fraction = float(np.mean(alternatives[judged] >= 1))
    if fraction <= CONTESTED_WARNING_FRACTION:
        return []
    return [
        f"{estimator} on {sequence.name}: {100 * fraction:.1f} % of its association decisions "
        f"without ids ({int((alternatives[judged] >= 1).sum())} of {int(judged.sum())}) had "
        "another interpretation within the new-landmark gate; one hypothesis may have paired "
        "wrongly and cannot revise it (ekf-slam-mht keeps the alternatives)"
    ]


def association_warnings(estimate: Estimate, sequence: Sequence, estimator: str) -> list[str]:
    """Warnings when too many known-id sightings were rejected or inflated (module doc), and
    when single-hypothesis association without ids was contested (``contested_warning``)."""
    diagnostics = estimate.diagnostics
    if len(diagnostics.assoc_t) == 0:
        return []
    known = _known_id_sightings(diagnostics, sequence)
    if not np.any(known):
        return contested_warning(estimate, sequence, estimator)
    t = diagnostics.assoc_t[known]
    decisions = diagnostics.assoc_decision[known]
    rejected = decisions == AssociationDecision.REJECTED.value
    inflated = (decisions == AssociationDecision.MATCHED.value) & (
        diagnostics.assoc_inflation[known] > 1.0
    )
    lines = []
    for flags, what in ((rejected, "rejected"), (inflated, "used with inflated noise")):
        fraction = float(np.mean(flags))
        if fraction <= ASSOCIATION_WARNING_FRACTION:
            continue
        worst = _worst_window(t[flags])
        lines.append(
            f"{estimator} on {sequence.name}: {100 * fraction:.1f} % of the known-id sightings "
            f"{what} ({int(flags.sum())} of {len(flags)}), most in the {WINDOW_S:g} s from "
            f"t={worst:.1f} s"
            + (": the stated noise is optimistic for this data" if what != "rejected" else "")
        )
    return lines


def _known_id_sightings(diagnostics, sequence: Sequence) -> np.ndarray:
    """(A,) bool: sightings of scans that carried ids: datasets with an ``ids`` option
    (the simulator, UTIAS, Victoria Park) say whether they attached them
    (``Sequence.landmark_ids``)."""
    return np.full(len(diagnostics.assoc_t), sequence.landmark_ids)


def _worst_window(times: np.ndarray) -> float:
    """Start [s] of the ``WINDOW_S`` window holding the most of ``times``."""
    times = np.sort(np.asarray(times, dtype=float))
    ends = np.searchsorted(times, times + WINDOW_S, side="right")
    best = int(np.argmax(ends - np.arange(len(times))))
    return float(times[best])
