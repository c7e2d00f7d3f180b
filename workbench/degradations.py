"""Degradations a run must not hide: said on the screen, written to metrics.json.

- **Data**: rows a loader dropped or repaired (``Sequence.metadata['counts']``, each count
  with its name), and the warnings a loader states (``Sequence.metadata['warnings']``).
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

WINDOW_S = 10.0


def data_warnings(sequence: Sequence) -> list[str]:
    """One line per non-zero count of dropped or repaired rows, and the loader's warnings."""
    lines = []
    counts = sequence.metadata.get("counts") or {}
    dropped = {name: int(value) for name, value in counts.items() if int(value) > 0}
    if dropped:
        listed = ", ".join(f"{name.replace('_', ' ')} {value}" for name, value in dropped.items())
        lines.append(f"{sequence.name}: rows dropped or repaired by the loader: {listed}")
    lines.extend(f"{sequence.name}: {text}" for text in sequence.metadata.get("warnings") or ())
    return lines


def association_warnings(estimate: Estimate, sequence: Sequence, estimator: str) -> list[str]:
    """Warnings when too many known-id sightings were rejected or inflated (module doc)."""
    diagnostics = estimate.diagnostics
    if len(diagnostics.assoc_t) == 0:
        return []
    known = _known_id_sightings(diagnostics, sequence)
    if not np.any(known):
        return []
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
    (the simulator, UTIAS, Victoria Park) say whether they attached them."""
    with_ids = (sequence.metadata.get("options") or {}).get("ids") is True
    return np.full(len(diagnostics.assoc_t), with_ids)


def _worst_window(times: np.ndarray) -> float:
    """Start [s] of the ``WINDOW_S`` window holding the most of ``times``."""
    times = np.sort(np.asarray(times, dtype=float))
    ends = np.searchsorted(times, times + WINDOW_S, side="right")
    best = int(np.argmax(ends - np.arange(len(times))))
    return float(times[best])
