"""Has an estimate diverged? Two signs that need no truth of the trajectory:

1. **Its sightings stopped fitting it, for good.** A consistent estimator's sightings fall
   inside their association or id gates (at 0.99, one in a hundred outside). An estimate
   that has left the region its covariance allows sees its later sightings outside their
   gates: rejected, left ambiguous, or used with their noise inflated to the gate
   (``filters.association.policy``). The run has diverged at ``t`` when from ``t`` to its
   end every window of ``WINDOW_S`` holds at least ``MIN_SIGHTINGS`` sightings and more than
   ``OUT_OF_GATE_FRACTION`` of them outside their gates, over at least ``MIN_SPAN_S``.
   A run whose stated noise is merely optimistic inflates some sightings all along (the
   degradation warning says so) but not most of them in every window to its end.
2. **It left the mapped area.** The landmarks a recording offers (the surveyed or true map
   where it has one, else the estimate's own final map) bound where a robot that sights
   them can be: their bounding box grown by the sensor's range (``NoiseSpec.landmark_range_m``)
   or, without one, by the box's diagonal. A pose outside it is not an estimate of that
   robot (UTIAS: a 10 m arena, and a fixed-lag run 640 m outside it).

3. **Its solver gave up.** A fixed-lag window whose updates stop fitting their own new
   factors (``smoothers.window_health``: ``window_diverged``), or a smoother whose GTSAM
   solver met an indeterminate system mid-run, on a graph it had solved before, and stopped
   there (``smoothers.keyframe_smoother``: ``solver_failed``); the earlier event is the time.

Each is reported with the time it began (``Divergence``), in metrics.json
(``diverged_at_s``, ``divergence``) and as a warning under every table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.estimate import AssociationDecision, Estimate
from datasets.sequence import Sequence

WINDOW_S = 30.0
"""Length of the windows the out-of-gate fraction is judged on [s]."""
MIN_SIGHTINGS = 20
"""Fewest sightings a window must hold to be judged."""
OUT_OF_GATE_FRACTION = 0.5
"""More than this fraction of a window's sightings outside their gates is not consistent."""
MIN_SPAN_S = 60.0
"""Shortest tail [s] of out-of-gate windows that counts as divergence, not a bad stretch."""


@dataclass(frozen=True)
class Divergence:
    """When an estimate diverged and the evidence."""

    t: float
    reason: str

    def line(self, estimator: str, dataset: str) -> str:
        return f"{estimator} on {dataset} diverged at t={self.t:.1f} s: {self.reason}"


def detect_divergence(estimate: Estimate, sequence: Sequence) -> Divergence | None:
    """The earliest sign of divergence (module docstring) in ``estimate``, or None."""
    found = [
        sign
        for sign in (
            _gates_abandoned(estimate),
            _outside_the_map(estimate, sequence),
            _solver_failed(estimate),
        )
        if sign is not None
    ]
    return min(found, key=lambda sign: sign.t) if found else None


def out_of_gate(estimate: Estimate) -> tuple[np.ndarray, np.ndarray]:
    """(times (A,) [s], outside (A,) bool) of every sighting: rejected for its distance,
    left ambiguous, or used inflated to its gate. Sightings rejected for what they are (a
    repeated id, a non-finite point) say nothing of the estimate and are left out."""
    diagnostics = estimate.diagnostics
    decisions = np.asarray(diagnostics.assoc_decision)
    reasons = np.asarray(diagnostics.assoc_reason)
    unusable = np.array(
        [("repeated" in str(r)) or ("non-finite" in str(r)) for r in reasons], dtype=bool
    )
    keep = ~unusable if len(unusable) else np.zeros(0, bool)
    outside = (
        (decisions == AssociationDecision.REJECTED.value)
        | (decisions == AssociationDecision.AMBIGUOUS.value)
        | (np.asarray(diagnostics.assoc_inflation, dtype=float) > 1.0)
    )
    return np.asarray(diagnostics.assoc_t, dtype=float)[keep], outside[keep]


def _solver_failed(estimate: Estimate) -> Divergence | None:
    """The earliest of the estimator's ``window_diverged`` and ``solver_failed`` events
    (module docstring, sign 3), if any."""
    said = {
        "window_diverged": "its fixed-lag window stopped fitting its new factors",
        "solver_failed": "its solver stopped, no estimate after it",
    }
    events = [event for event in estimate.diagnostics.events if event.kind in said]
    if not events:
        return None
    first = min(events, key=lambda event: event.t)
    return Divergence(float(first.t), f"{said[first.kind]} ({first.details['reason']})")


def _gates_abandoned(estimate: Estimate) -> Divergence | None:
    t, outside = out_of_gate(estimate)
    if len(t) < MIN_SIGHTINGS:
        return None
    order = np.argsort(t, kind="stable")
    t, outside = t[order], outside[order]
    end = t[-1]
    # windows from the end backward by half a window; the tail is diverged from the
    # earliest start of the unbroken run of out-of-gate windows that reaches the end
    # (a window with too few sightings to judge neither breaks nor extends it)
    earliest = None
    for start in np.arange(end - WINDOW_S, t[0] - 1e-9, -WINDOW_S / 2):
        window = (t >= start) & (t <= start + WINDOW_S)
        if window.sum() < MIN_SIGHTINGS:
            continue
        if outside[window].mean() <= OUT_OF_GATE_FRACTION:
            break
        earliest = float(start)
    if earliest is None:
        return None
    began = earliest
    if end - began < MIN_SPAN_S:
        return None
    tail = t >= began
    return Divergence(
        float(began),
        f"{100 * outside[tail].mean():.0f} % of its {int(tail.sum())} sightings from then to "
        f"the end fell outside their gates (more than {100 * OUT_OF_GATE_FRACTION:.0f} % in "
        f"every {WINDOW_S:g} s window of {MIN_SIGHTINGS} or more)",
    )


def _outside_the_map(estimate: Estimate, sequence: Sequence) -> Divergence | None:
    """The first pose (causal, else smoothed) outside the mapped area (module docstring)."""
    histories = (estimate.causal, estimate.smoothed)
    poses = [h.pose for h in histories if h is not None and h.pose is not None and len(h.pose)]
    if not poses:
        return None
    pose = poses[0]
    landmarks, source = _reference_map(estimate, sequence)
    if landmarks is None or len(landmarks) < 2:
        return None
    d = min(landmarks.shape[1], pose.positions.shape[1])
    low, high = landmarks[:, :d].min(axis=0), landmarks[:, :d].max(axis=0)
    reach = sequence.noise.landmark_range_m
    margin = float(reach) if reach else float(np.linalg.norm(high - low))
    positions = pose.positions[:, :d]
    away = np.any((positions < low - margin) | (positions > high + margin), axis=1)
    away &= np.all(np.isfinite(positions), axis=1)
    if not away.any():
        return None
    first = int(np.flatnonzero(away)[0])
    farthest = float(
        np.max(
            np.linalg.norm(np.maximum(low - positions, 0) + np.maximum(positions - high, 0), axis=1)
        )
    )
    return Divergence(
        float(pose.t[first]),
        f"its position left the area of {source} grown by {margin:.3g} m "
        f"({int(away.sum())} of {len(away)} poses outside, up to {farthest:.3g} m from it)",
    )


def _reference_map(estimate: Estimate, sequence: Sequence) -> tuple[np.ndarray | None, str]:
    """The landmarks that bound the robot: surveyed, true, or the estimate's own map."""
    for landmark_map, source in (
        (sequence.known_landmarks, "the surveyed landmarks"),
        (
            None if sequence.ground_truth is None else sequence.ground_truth.landmarks,
            "the true map",
        ),
        (estimate.landmarks, "its own map"),
    ):
        if landmark_map is not None and len(landmark_map.positions):
            positions = np.asarray(landmark_map.positions, dtype=float)
            positions = positions[np.all(np.isfinite(positions), axis=1)]
            if len(positions):
                return positions, source
    return None, ""
