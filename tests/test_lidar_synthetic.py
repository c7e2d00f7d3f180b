"""Synthetic lidar world: geometry, path, ray caster, IMU in the bag, sidecar, options."""

from __future__ import annotations

import json

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.lidar.corner_truth import observable, read_corner_truth, true_corner_ids
from datasets.synthetic_lidar import sidecar_path, write_lidar_bag
from datasets.synthetic_lidar.lidar import LidarModel, cast_rays, sweep
from datasets.synthetic_lidar.path import LoopPath
from datasets.synthetic_lidar.world import corridor_world
from datasets.trajectory import Trajectory


def test_world_corners_and_normals():
    world = corridor_world()
    positions, normals, heights = world.corners()
    assert (
        len(positions) == 20 + 4 + 4 * 4 + 5 * 4
    )  # boundary with 4 alcoves, inner block, boxes, pillars
    assert np.allclose(np.linalg.norm(normals, axis=2), 1.0)
    # outer corner (0, 0) of the boundary: free space is +x, +y
    k = int(np.argmin(np.linalg.norm(positions - [0.0, 0.0], axis=1)))
    assert sorted(map(tuple, np.round(normals[k], 6))) == [(0.0, 1.0), (1.0, 0.0)]
    # inner block corner (5, 5): free space is -x, -y
    k = int(np.argmin(np.linalg.norm(positions - [5.0, 5.0], axis=1)))
    assert sorted(map(tuple, np.round(normals[k], 6))) == [(-1.0, 0.0), (0.0, -1.0)]


def test_path_closes_and_derivatives_match():
    path = LoopPath(speed_m_s=1.5)
    period = path.length_m / 1.5
    t = np.linspace(0.0, period, 40001)
    motion = path.sample(t)
    assert np.allclose(motion.position[0], motion.position[-1], atol=1e-6) and motion.yaw[
        0
    ] == pytest.approx(motion.yaw[-1], abs=1e-9)
    dt = t[1] - t[0]
    assert np.abs(np.gradient(motion.position, dt, axis=0) - motion.velocity)[1:-1].max() < 1e-3
    assert np.abs(np.gradient(motion.velocity, dt, axis=0) - motion.acceleration)[1:-1].max() < 5e-3
    assert np.abs(np.gradient(np.unwrap(motion.yaw), dt) - motion.yaw_rate)[1:-1].max() < 5e-3
    assert (
        np.max(np.abs(np.diff(motion.yaw_rate))) < 0.01
    )  # continuous yaw rate (a circular arc would jump 0.75 rad/s)
    world = corridor_world()  # the path stays in free space, at least 0.9 m from any wall
    a, b = world.wall_start, world.wall_end
    e = b - a
    u = np.clip(
        np.einsum("psd,sd->ps", motion.position[::20, None] - a[None], e) / np.sum(e * e, axis=1),
        0,
        1,
    )
    gap = np.linalg.norm(motion.position[::20, None] - (a[None] + u[..., None] * e[None]), axis=2)
    assert gap.min() > 0.9


def test_ray_cast_distances():
    world = corridor_world()
    origins = np.array([[15.0, 2.5, 1.0]] * 3)
    directions = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    assert np.allclose(cast_rays(world, origins, directions, 40.0), [2.5, 2.5, 1.0])
    up = cast_rays(world, origins[:1], np.array([[0.0, 0.0, 1.0]]), 40.0)
    assert np.isinf(up[0])


def test_sweep_points_are_on_walls_in_their_own_frame():
    world, path = corridor_world(), LoopPath()
    model = LidarModel(columns=360, range_sigma_m=0.0)
    scan = sweep(world, path, model, 3.0, np.random.default_rng(0))
    assert scan.points.shape == (16, 360, 3) and np.isnan(scan.points).any()
    # a point mapped to the world with the pose at its own column time lies on a wall or floor
    motion = path.sample(3.0 + scan.column_times)
    c, s = np.cos(motion.yaw), np.sin(motion.yaw)
    local = scan.points[8]  # a beam at +1 deg: hits walls
    x = motion.position[:, 0] + c * local[:, 0] - s * local[:, 1]
    y = motion.position[:, 1] + s * local[:, 0] + c * local[:, 1]
    a, b = world.wall_start, world.wall_end
    e = b - a
    p = np.column_stack([x, y])
    hit = np.isfinite(p[:, 0])
    u = np.clip(np.einsum("psd,sd->ps", p[hit, None] - a[None], e) / np.sum(e * e, axis=1), 0, 1)
    gap = np.linalg.norm(p[hit, None] - (a[None] + u[..., None] * e[None]), axis=2).min(axis=1)
    assert gap.max() < 1e-6


def test_bag_imu_and_sidecar(tmp_path):
    from datasets.bags.source import load_bag

    bag = write_lidar_bag(
        tmp_path / "demo",
        5,
        "ros2",
        {
            "duration_s": "0.3",
            "columns": "128",
            "gyro_noise_density": "0",
            "accel_noise_density": "0",
            "start_s": "8",
        },
    )
    sidecar = json.loads(sidecar_path(bag).read_text())
    assert sidecar["format"] == "workbench-corners-1" and len(sidecar["corners"]) == 60
    truth = read_corner_truth(sidecar_path(bag))
    assert np.allclose(truth.positions[:, 2], 1.0) and truth.wall_start.shape == (60, 2)
    sequence = load_bag(str(bag), 0, {"odometry": "false", "corners": "false"})
    imu = [m for m in sequence.measurements() if type(m).__name__ == "ImuSample"]
    path = LoopPath()
    motion = path.sample(8.0 + np.array([m.t for m in imu]) - 1_700_000_000)
    assert np.allclose([m.gyro[2] for m in imu], motion.yaw_rate, atol=1e-6)
    c, s = np.cos(motion.yaw), np.sin(motion.yaw)
    forward = c * motion.acceleration[:, 0] + s * motion.acceleration[:, 1]
    assert np.allclose([m.accel[0] for m in imu], forward, atol=1e-6)
    assert np.allclose([m.accel[2] for m in imu], 9.81)
    # observability: from the start pose some corners are visible, none through the inner block
    seen = observable(truth, np.array([15.0, 2.5]), 1.0, 0.5, 15.0, 0.25)
    assert 0 < seen.sum() < 20
    assert not np.any(seen & (truth.positions[:, 1] > 15.0))


def test_options_are_checked(tmp_path):
    with pytest.raises(InputError, match="beams must be 16 or 32"):
        write_lidar_bag(tmp_path / "x", 0, "ros1", {"beams": "12"})
    with pytest.raises(InputError, match="--format must be ros1 or ros2"):
        write_lidar_bag(tmp_path / "x", 0, "ros3", {})
    with pytest.raises(InputError, match="duratoin_s"):
        write_lidar_bag(tmp_path / "x", 0, "ros1", {"duratoin_s": "1"})
    bag = write_lidar_bag(
        tmp_path / "y", 0, "ros1", {"duration_s": "0.1", "columns": "64", "beams": "32"}
    )
    assert bag.name == "y.bag" and bag.is_file() and not list(tmp_path.glob(".*partial*"))
    with pytest.raises(InputError, match="exists already"):
        write_lidar_bag(tmp_path / "y.bag", 0, "ros1", {})


def test_true_corner_ids(tmp_path):
    bag = write_lidar_bag(tmp_path / "ids", 0, "ros1", {"duration_s": "0.1", "columns": "64"})
    truth = read_corner_truth(sidecar_path(bag))
    yaw = 0.3
    quat = np.array([[np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]] * 2)
    pose = Trajectory(np.array([0.0, 1.0]), np.array([[15.0, 2.5, 1.0]] * 2), quat)
    rotation = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    body = (truth.positions[[3, 7]] - [15.0, 2.5, 1.0]) @ rotation  # R^T (rho - r)
    detections = np.vstack([body + [0.05, -0.03, 0.0], [[50.0, 50.0, 0.0]]])
    ((t, ids),) = true_corner_ids(
        [(0.5, detections), (0.6, np.zeros((0, 3))), (2.0, detections)], truth, pose
    )
    assert t == 0.5 and list(ids) == [int(truth.ids[3]), int(truth.ids[7]), -1]
