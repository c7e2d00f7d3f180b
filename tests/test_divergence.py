"""Divergence is detected from the estimate alone (``workbench.metrics.divergence``): its
sightings leaving their gates for good, or its position leaving the mapped area."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.estimate import AssociationDecision, EstimateRecorder
from datasets.sequence import NoiseSpec, Sequence
from datasets.state import Frame, LandmarkMap
from workbench.metrics.divergence import (
    MIN_SPAN_S,
    OUT_OF_GATE_FRACTION,
    detect_divergence,
)

MATCHED, REJECTED = AssociationDecision.MATCHED, AssociationDecision.REJECTED


def _sequence(landmarks: np.ndarray | None = None, reach_m: float | None = 5.0) -> Sequence:
    known = (
        None
        if landmarks is None
        else LandmarkMap(np.arange(len(landmarks)), landmarks, frame=Frame.WORLD)
    )
    return Sequence(
        name="test",
        dimension=2,
        sensors=frozenset(),
        stream=lambda: iter(()),
        noise=NoiseSpec(landmark_range_m=reach_m),
        known_landmarks=known,
    )


def _estimate(
    duration_s: float,
    outside_from_s: float | None,
    outside_fraction: float = 0.9,
    positions=None,
    seed: int = 0,
):
    """Ten sightings a second; from ``outside_from_s`` on, ``outside_fraction`` of them
    inflated to their gate, before it one in a hundred (a consistent filter at 0.99)."""
    rng = np.random.default_rng(seed)
    recorder = EstimateRecorder(2)
    times = np.arange(0.0, duration_s, 0.1)
    for k, t in enumerate(times):
        position = np.zeros(2) if positions is None else positions(t)
        recorder.pose(t, position, 0.0, np.eye(3) * 0.01)
        late = outside_from_s is not None and t >= outside_from_s
        probability = outside_fraction if late else 0.01
        inflation = 3.0 if rng.random() < probability else 1.0
        recorder.association(t, 0, k % 5, MATCHED, "", inflation)
    return recorder.build()


def test_a_consistent_run_has_not_diverged() -> None:
    assert detect_divergence(_estimate(300.0, None), _sequence()) is None


def test_sightings_leaving_their_gates_for_good_is_divergence_from_when_it_began() -> None:
    found = detect_divergence(_estimate(300.0, 120.0), _sequence())
    assert found is not None
    assert 120.0 - 30.0 <= found.t <= 120.0 + 15.0  # within a window step of the onset
    assert "outside their gates" in found.reason
    line = found.line("smoother-fixed-lag", "utias")
    assert line.startswith("smoother-fixed-lag on utias diverged at t=")


@pytest.mark.parametrize(
    ("outside_from_s", "fraction", "why"),
    [
        (280.0, 0.9, "a bad last 20 s is shorter than MIN_SPAN_S"),
        (100.0, OUT_OF_GATE_FRACTION - 0.15, "optimistic noise, not divergence"),
    ],
)
def test_short_or_partial_departures_are_not_divergence(
    outside_from_s: float, fraction: float, why: str
) -> None:
    assert 300.0 - 280.0 < MIN_SPAN_S
    found = detect_divergence(_estimate(300.0, outside_from_s, fraction), _sequence())
    assert found is None, why


def test_a_stretch_that_recovers_is_not_divergence() -> None:
    recorder = EstimateRecorder(2)
    for k, t in enumerate(np.arange(0.0, 300.0, 0.1)):
        recorder.pose(t, np.zeros(2), 0.0, np.eye(3))
        bad = 100.0 <= t < 200.0
        recorder.association(t, 0, 0, REJECTED if bad else MATCHED, "gate" if bad else "")
    assert detect_divergence(recorder.build(), _sequence()) is None


def test_leaving_the_mapped_area_is_divergence() -> None:
    landmarks = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]])

    def runaway(t: float) -> np.ndarray:
        return np.array([5.0 + max(0.0, t - 50.0) * 2.0, 4.0])  # leaves the 10 m box + 5 m

    found = detect_divergence(_estimate(100.0, None, positions=runaway), _sequence(landmarks))
    assert found is not None
    assert found.t == pytest.approx(50.0 + (15.0 - 5.0) / 2.0, abs=0.11)
    assert "surveyed landmarks" in found.reason
    inside = detect_divergence(_estimate(100.0, None), _sequence(landmarks))
    assert inside is None
