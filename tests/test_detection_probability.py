"""P_D by range: the model's bins, and the fit against a reference recovering a known P_D."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.detection_probability import (
    DetectionProbability,
    fit_detection_probability,
    in_view,
)
from datasets.errors import InputError


def test_bins_are_half_open_and_the_last_one_unbounded() -> None:
    model = DetectionProbability((1.0, 2.0), (0.2, 0.7, 0.4), "test")
    np.testing.assert_array_equal(
        model.at(np.array([0.0, 0.99, 1.0, 1.5, 2.0, 50.0])), [0.2, 0.2, 0.7, 0.7, 0.4, 0.4]
    )
    with pytest.raises(InputError, match="range bins"):
        DetectionProbability((1.0,), (0.5,), "test")
    with pytest.raises(InputError, match=r"\(0, 1\)"):
        DetectionProbability((1.0,), (0.5, 1.0), "test")


def test_view_is_the_field_of_view_and_the_range() -> None:
    points = np.array([[2.0, 0.0], [2.0, 2.1], [-1.0, 0.0], [6.0, 0.0]])
    np.testing.assert_array_equal(in_view(points, 90.0, 5.0), [True, False, False, False])
    np.testing.assert_array_equal(in_view(points, None, None), [True] * 4)


def test_fit_recovers_a_known_detection_probability_by_range() -> None:
    """A robot turning on the spot among landmarks at 0.5-5.5 m, each in view sighted with
    P_D 0.8 within 2 m and 0.3 beyond (seeded): the fitted bins agree within 3 binomial
    standard deviations, and landmarks out of view never count."""
    rng = np.random.default_rng(4)
    angles = rng.uniform(-np.pi, np.pi, 60)
    radii = rng.uniform(0.5, 5.5, 60)
    landmarks = {
        100 + k: np.array([np.cos(a) * r, np.sin(a) * r])
        for k, (a, r) in enumerate(zip(angles, radii))
    }
    truth_t = np.arange(0.0, 400.0, 0.1)
    reference = (truth_t, np.zeros((len(truth_t), 2)), 0.05 * truth_t)
    scans = []
    for t in np.arange(0.0, 399.0, 0.5):
        heading = 0.05 * t
        rotation = np.array(
            [[np.cos(heading), -np.sin(heading)], [np.sin(heading), np.cos(heading)]]
        )
        sighted = []
        for landmark_id, position in landmarks.items():
            body = position @ rotation  # R^T l, the robot at the origin
            if in_view(body[None], 60.0, 6.0)[0]:
                p_d = 0.8 if np.linalg.norm(body) < 2.0 else 0.3
                if rng.random() < p_d:
                    sighted.append(landmark_id)
        scans.append((float(t), np.array(sighted, dtype=int)))
    model = fit_detection_probability(scans, reference, landmarks, 60.0, 6.0, "test", 1.0)
    assert model.range_edges_m == (1.0, 2.0, 3.0, 4.0, 5.0)
    expected = np.array([0.8, 0.8, 0.3, 0.3, 0.3, 0.3])
    counts = np.array(model.counts)
    fitted = np.array(model.probability)
    used = counts > 50
    assert used.sum() >= 5
    spread = np.sqrt(expected * (1 - expected) / np.maximum(counts, 1))
    assert np.all(np.abs(fitted - expected)[used] < 3 * spread[used] + 2 / counts[used])
    # the field of view limits what counts: without it every landmark in range counts in
    # every scan (the 60 degree view holds about a sixth of them at a time)
    everywhere = fit_detection_probability(scans, reference, landmarks, None, 6.0, "test", 1.0)
    assert sum(everywhere.counts) > 4 * sum(model.counts)
    with pytest.raises(InputError, match="no scans"):
        fit_detection_probability([], reference, landmarks, 60.0, 6.0, "nowhere")
