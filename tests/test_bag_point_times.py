"""``--data point_times=azimuth`` on bags: clouds without per-point times are timed by their
lidar-frame azimuths over the lidar topic's sweep (``datasets.lidar.sweep_times``), as scan
folders are; a cloud with times of its own is refused, naming the bag, topic and time. (The
real KITTI clip read from bags with the option: ``tests/test_lidar_clip_bags.py``.)"""

from __future__ import annotations

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.lidar.sweep_times import azimuth_point_times
from datasets.measurements import Odometry, PointCloud
from tests.test_bags_bad_input import _box_points, _cloud, write_ros2
from workbench.registry import load_dataset

DATA = {"kiss.max_num_threads": "1", "point_times": "azimuth"}


def _untimed_bag(path, rng, period_s: float = 0.1, frames: int = 6):
    """A ROS 2 bag of ``frames`` clouds of a box room, no time field, ``period_s`` apart."""
    clouds = [_box_points(rng) for _ in range(frames)]
    stamps = 2.0 + period_s * np.arange(frames)
    messages = [
        ("/cloud", "sensor_msgs/msg/PointCloud2", t, _cloud(t, points))
        for t, points in zip(stamps, clouds, strict=True)
    ]
    return write_ros2(path, messages), clouds, stamps


def test_untimed_bag_clouds_get_azimuth_times_in_the_lidar_frame(tmp_path) -> None:
    """The times are those of the lidar-frame points (before ``lidar_to_body``, here a 90 deg
    yaw that would change every azimuth), over the topic's 0.08 s frame interval; the
    sequence starts where the first sweep ends (its stamp plus half a sweep), as for a
    deskewed cloud with times of its own."""
    bag, clouds, stamps = _untimed_bag(tmp_path / "untimed", np.random.default_rng(3), 0.08)
    yaw90 = "[0.0, 0.0, 0.0, 0.7071067811865476, 0.0, 0.0, 0.7071067811865476]"
    sequence = load_dataset(f"bag:{bag}", 0, {**DATA, "lidar_to_body": yaw90})
    measurements = list(sequence.measurements())
    emitted = [m for m in measurements if isinstance(m, PointCloud)]
    assert len(emitted) == len(clouds) - 1  # the first sweep is read, not emitted
    for cloud in emitted:
        index = int(np.argmin(np.abs(stamps - cloud.t)))
        stored = clouds[index].astype(np.float32).astype(float)
        np.testing.assert_allclose(
            cloud.point_times, azimuth_point_times(stored, 0.08), atol=1e-9, rtol=0
        )
        # the body-frame points are the lidar's turned by 90 deg: x_body = -y_lidar
        np.testing.assert_allclose(cloud.points[:, 0], -stored[:, 1], atol=1e-5)
    first_end = stamps[0] + float(np.max(azimuth_point_times(clouds[0], 0.08)))
    assert sequence.initial_state.t == pytest.approx(first_end, abs=1e-6)
    first_odometry = next(m for m in measurements if isinstance(m, Odometry))
    assert first_odometry.t - first_odometry.dt == pytest.approx(first_end, abs=1e-6)


def test_without_the_option_untimed_bag_clouds_stay_untimed(tmp_path) -> None:
    bag, _, stamps = _untimed_bag(tmp_path / "untimed", np.random.default_rng(4))
    sequence = load_dataset(f"bag:{bag}", 0, {"kiss.max_num_threads": "1"})
    clouds = [m for m in sequence.measurements() if isinstance(m, PointCloud)]
    assert clouds and all(cloud.point_times is None for cloud in clouds)
    assert sequence.initial_state.t == pytest.approx(stamps[0], abs=1e-9)


def test_a_bag_whose_clouds_have_times_is_refused_with_the_option(tmp_path) -> None:
    rng = np.random.default_rng(5)
    points = np.column_stack([_box_points(rng), np.linspace(0.0, 0.09, 2000)])
    messages = [
        ("/cloud", "sensor_msgs/msg/PointCloud2", t, _cloud(t, points, ("x", "y", "z", "t")))
        for t in 2.0 + 0.1 * np.arange(4)
    ]
    bag = write_ros2(tmp_path / "timed", messages)
    with pytest.raises(InputError) as error:
        list(load_dataset(f"bag:{bag}", 0, DATA).measurements())
    text = str(error.value)
    assert str(bag) in text and "/cloud" in text and "t=2.0" in text
    assert "point_times=azimuth is for clouds without them" in text


def test_a_single_cloud_gives_no_sweep_period(tmp_path) -> None:
    bag, _, _ = _untimed_bag(tmp_path / "one", np.random.default_rng(6), frames=1)
    with pytest.raises(InputError, match="sweep period"):
        load_dataset(f"bag:{bag}", 0, DATA)
