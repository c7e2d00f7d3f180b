"""Association precision/recall, majority id mapping and loop-closure precision on a hand-made log."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.estimate import AssociationDecision, EstimateRecorder
from datasets.state import GroundTruth, LandmarkMap, StateHistory
from workbench.metrics.data_association import (
    landmark_id_mapping,
    majority_mapping,
    score_associations,
    score_loop_closures,
    true_ids_of_records,
)

SCAN_IDS = (
    (0.0, np.array([5, 6])),
    (1.0, np.array([5, 6, 7])),
    (2.0, np.array([6, 7, 5])),
    (3.0, np.array([8])),
)


def _decision(map_id: int, is_new: bool) -> AssociationDecision:
    if is_new:
        return AssociationDecision.NEW
    return AssociationDecision.MATCHED if map_id >= 0 else AssociationDecision.REJECTED


def _diagnostics():
    recorder = EstimateRecorder(dimension=3)
    log = [
        (0.0, 0, 100, True), (0.0, 1, 101, True),
        (1.0, 0, 100, False), (1.0, 1, 100, False), (1.0, 2, 102, True),  # 6 wrongly onto 100
        (2.0, 0, 101, False), (2.0, 1, 103, True), (2.0, 2, 100, False),  # 7 duplicated as 103
        (3.0, 0, -1, False),  # rejected
    ]  # fmt: skip
    for t, index, map_id, is_new in log:
        recorder.association(t, index, map_id, _decision(map_id, is_new))
    recorder.event(2.5, "loop_closure", pairs=[[102, 103]])
    recorder.event(2.8, "loop_closure", pairs=[[100, 101], [100, 999]])
    recorder.event(2.9, "skipped_scan")
    return recorder.diagnostics()


def test_true_ids_are_looked_up_by_scan_time_and_index() -> None:
    diagnostics = _diagnostics()
    np.testing.assert_array_equal(
        true_ids_of_records(diagnostics, SCAN_IDS), [5, 6, 5, 6, 7, 6, 7, 5, 8]
    )
    shifted = tuple((t + 0.5, ids) for t, ids in SCAN_IDS)
    assert np.all(true_ids_of_records(diagnostics, shifted) == -1)


def test_majority_mapping_prefers_the_most_frequent_then_the_smallest_id() -> None:
    mapping = majority_mapping(np.array([1, 1, 1, 2, 2, -1]), np.array([4, 3, 4, 9, 8, 7]))
    assert mapping == {1: 4, 2: 8}


def test_precision_and_recall_of_the_decisions() -> None:
    score = score_associations(_diagnostics(), SCAN_IDS)
    # Associations: (1,0) ok, (1,1) wrong, (2,0) ok, (2,2) ok.
    assert (score.associations, score.correct) == (4, 3)
    # Positives: landmark already mapped earlier: (1,0) (1,1) (2,0) (2,1) (2,2).
    assert score.positives == 5
    assert score.precision == pytest.approx(0.75)
    assert score.recall == pytest.approx(0.6)
    assert (score.new_landmarks, score.rejected, score.records) == (4, 1, 9)


def test_an_associated_anchor_counts_as_a_positive() -> None:
    recorder = EstimateRecorder(dimension=3)
    recorder.association(0.0, 0, 42, AssociationDecision.MATCHED)  # known: no creation record
    score = score_associations(recorder.diagnostics(), ((0.0, np.array([42])),))
    assert (score.precision, score.recall) == (1.0, 1.0)


def test_loop_closure_pairs_are_scored_through_the_mapping() -> None:
    diagnostics = _diagnostics()
    mapping = majority_mapping(
        diagnostics.assoc_landmark_id, true_ids_of_records(diagnostics, SCAN_IDS)
    )
    assert mapping == {100: 5, 101: 6, 102: 7, 103: 7}
    score = score_loop_closures(diagnostics.events, mapping)
    assert (score.events, score.pairs, score.scored, score.correct) == (2, 3, 2, 1)
    assert score.precision == pytest.approx(0.5)


def test_landmark_id_mapping_fills_unrecorded_ids_with_themselves() -> None:
    truth = GroundTruth(
        history=StateHistory(),
        landmarks=LandmarkMap(ids=np.array([5, 6, 7, 8, 100]), positions=np.zeros((5, 3))),
        scan_ids=SCAN_IDS,
    )
    mapping = landmark_id_mapping(_diagnostics(), truth)
    # 100 keeps its majority (5) although a true landmark 100 exists; 8 is filled.
    assert mapping[100] == 5 and mapping[8] == 8 and mapping[103] == 7
