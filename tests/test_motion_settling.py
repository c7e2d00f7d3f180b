"""Warm-up criterion: KISS-ICP's increments and corners inflated until the
corners accept its motion in consecutive frames (``datasets.lidar.motion_settling``)."""

from __future__ import annotations

import numpy as np

from datasets.lidar.motion_settling import SETTLED_FRAMES, MotionSettling


def _frame(rng, error_m, corners=4, sigma=0.02):
    """Corners of one frame against their previous sightings: every difference is minus the
    increment's translation error (world frame) plus the two detections' noise."""
    covariance = np.repeat((2.0 * sigma**2 * np.eye(2))[None], corners, axis=0)
    noise = rng.normal(0.0, np.sqrt(2.0) * sigma, (corners, 2))
    return -np.asarray(error_m, dtype=float) + noise, covariance


def test_biased_increments_are_inflated_until_the_corners_accept_three_in_a_row():
    rng = np.random.default_rng(3)
    settling = MotionSettling()
    inflations = []
    for frame, error in enumerate([(0.08, 0.0)] * 5 + [(0.0, 0.0)] * 6, start=1):
        inflations.append(settling.increment_inflation(frame, *_frame(rng, error)))
    # 8 cm off with four 2 cm corners: every such frame fails and is inflated by about the
    # error's square
    for extra in inflations[:5]:
        assert extra is not None
        assert 0.5 * 0.08**2 < extra[0, 0] < 2.0 * 0.08**2
    # then three passes in a row settle it, at the third; nothing is inflated after that
    assert settling.settled_frame == 5 + SETTLED_FRAMES
    assert all(extra is None for extra in inflations[5 + SETTLED_FRAMES - 1 :])
    assert settling.inflated_frames == 5 + SETTLED_FRAMES - 1
    # once settled it stays so, whatever later frames show
    assert settling.increment_inflation(20, *_frame(rng, (0.2, 0.0))) is None


def test_a_frame_without_corners_changes_nothing_and_a_failure_restarts_the_count():
    rng = np.random.default_rng(4)
    settling = MotionSettling()
    assert settling.increment_inflation(1, np.zeros((0, 2)), np.zeros((0, 2, 2))) is None
    assert settling.streak == 0 and settling.inflated_frames == 0
    settling.increment_inflation(2, *_frame(rng, (0.0, 0.0)))
    settling.increment_inflation(3, *_frame(rng, (0.0, 0.0)))
    assert settling.streak == 2
    settling.increment_inflation(4, *_frame(rng, (0.0, 0.1)))
    assert settling.streak == 0 and settling.settled_frame is None


def test_correct_increments_settle_at_the_third_frame_in_most_recordings():
    """The test's false alarms: with a right increment each frame fails with probability
    0.01, so 200 recordings settle at frame 3 about 97 % of the time."""
    at_third = 0
    for seed in range(200):
        rng = np.random.default_rng(seed)
        settling = MotionSettling()
        for frame in range(1, 20):
            settling.increment_inflation(frame, *_frame(rng, (0.0, 0.0)))
            if settling.settled_frame is not None:
                break
        at_third += settling.settled_frame == SETTLED_FRAMES
    assert at_third >= 185


def test_the_warm_up_gives_up_at_its_limit_and_the_front_end_warns():
    """Corners that never accept the increments (8 cm off in every frame) inflate until
    LIMIT_FRAMES, then nothing more is inflated, and the front end says so in a warning
    (which the bag and scan loaders add to the sequence's warnings)."""
    from datasets.lidar.frontend import LidarFrontEnd
    from datasets.lidar.frontend_settings import FrontEndSettings
    from datasets.lidar.motion_settling import LIMIT_FRAMES

    rng = np.random.default_rng(5)
    front_end = LidarFrontEnd(FrontEndSettings())
    settling = front_end.settling
    assert front_end.settling_warning() is None
    inflations = [
        settling.increment_inflation(frame, *_frame(rng, (0.08, 0.0)))
        for frame in range(1, LIMIT_FRAMES + 5)
    ]
    assert all(extra is not None for extra in inflations[: LIMIT_FRAMES - 1])
    assert all(extra is None for extra in inflations[LIMIT_FRAMES - 1 :])
    assert settling.settled_frame is None and settling.gave_up_frame == LIMIT_FRAMES
    assert settling.inflated_frames == LIMIT_FRAMES - 1
    warning = front_end.settling_warning()
    assert warning is not None and f"up to frame {LIMIT_FRAMES}" in warning
