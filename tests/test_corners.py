"""Corner extractor: geometry, thresholds, split-and-merge, and the propagated covariance
checked against Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.lidar.corner_config import CornerConfig
from datasets.lidar.corner_scan import azimuth_scan_indices
from datasets.lidar.corner_segments import split_segments
from datasets.lidar.corners import extract_corners, scan_corners
from datasets.synthetic_lidar.lidar import cast_rays
from datasets.synthetic_lidar.world import Polygon, World


def _room_world(extra: list[Polygon] | None = None) -> World:
    room = Polygon(np.array([[-4.0, -3.0], [6.0, -3.0], [6.0, 5.0], [-4.0, 5.0]]), 3.0, "boundary")
    return World.from_polygons(tuple([room] + (extra or [])))


def _scan(
    world: World,
    rng: np.random.Generator,
    range_sigma=0.0,
    bearing_sigma=0.0,
    columns=1440,
    sensor=(0.0, 0.0, 1.0),
) -> np.ndarray:
    """A single horizontal ring (plus a ring 1 deg up) from ``sensor``, body frame = world axes."""
    azimuth = np.linspace(-np.pi, np.pi, columns, endpoint=False)
    points = []
    for elevation in np.deg2rad([0.0, 1.0]):
        measured = azimuth + rng.normal(0.0, bearing_sigma, columns) if bearing_sigma else azimuth
        directions = np.column_stack(
            [
                np.cos(elevation) * np.cos(azimuth),
                np.cos(elevation) * np.sin(azimuth),
                np.full(columns, np.sin(elevation)),
            ]
        )
        distance = cast_rays(world, np.tile(sensor, (columns, 1)), directions, 50.0)
        distance = distance + (rng.normal(0.0, range_sigma, columns) if range_sigma else 0.0)
        # the range is measured along the true ray; the bearing error moves the reported point
        reported = np.column_stack(
            [
                np.cos(elevation) * np.cos(measured),
                np.cos(elevation) * np.sin(measured),
                np.full(columns, np.sin(elevation)),
            ]
        )
        points.append(distance[:, None] * reported)
    return np.concatenate(points)


def test_azimuth_scan_takes_the_most_horizontal_point_then_the_bin_centre():
    """One point per bin, nearest the slab centre; equally near ones (KITTI's z is quantised
    to 1 mm) go to the one nearest the bin's centre azimuth, whatever the file order."""
    config = CornerConfig(azimuth_resolution_deg=1.0)
    bin_centre_deg = 10.5 - 180.0  # bins count from azimuth -180 deg
    rows = []
    for degrees, z in [(0.1, 0.05), (0.5, 0.05), (0.9, 0.05), (0.3, 0.01)]:  # bin 10 of 360
        azimuth = np.deg2rad(bin_centre_deg - 0.5 + degrees)
        rows.append([5.0 * np.cos(azimuth), 5.0 * np.sin(azimuth), z])
    for degrees, z in [(0.2, -0.03), (0.5, 0.03), (0.7, 0.03)]:  # bin 11: a tie at +-0.03
        azimuth = np.deg2rad(bin_centre_deg + 0.5 + degrees)
        rows.append([5.0 * np.cos(azimuth), 5.0 * np.sin(azimuth), z])
    rows.append([0.0, 0.0, 5.0])  # outside the slab
    points = np.array(rows)
    for order in (np.arange(len(points)), np.arange(len(points))[::-1]):
        chosen = order[azimuth_scan_indices(points[order], config)[0]]
        assert chosen.tolist() == [3, 5]


def test_room_and_box_corners_exact_without_noise():
    box = Polygon(np.array([[2.0, 1.0], [3.0, 1.0], [3.0, 2.0], [2.0, 2.0]]), 1.5, "obstacle")
    points = _scan(_room_world([box]), np.random.default_rng(0))
    corners = extract_corners(points, CornerConfig(max_range_m=20.0))
    # the box hides the room corner (6, 5); of the box, only (2, 1) joins two visible faces:
    # (3, 1) and (2, 2) end a visible face at a hidden one (jump edges, not corners)
    expected = np.array([[-4, -3], [6, -3], [-4, 5], [2, 1]], dtype=float)
    found = corners.points[:, :2]
    gaps = np.linalg.norm(found[:, None] - expected[None], axis=2)
    assert len(found) == 4
    assert np.all(gaps.min(axis=1) < 0.005) and np.all(gaps.min(axis=0) < 0.005)
    assert np.allclose(corners.points[:, 2], 0.0)
    assert corners.covariances.shape == (len(found), 3, 3)
    assert np.all(np.linalg.eigvalsh(corners.covariances) > 0)


def test_a_deskewed_scan_keeps_the_sensor_order_and_finds_the_same_corners():
    """Deskewing moves the azimuth scan's points after their selection; ``scan_corners``
    keeps the order and bins the sensor measured them in, so the corners move with the
    points and none is lost: a rigid shift moves every corner by exactly the shift (their
    covariances follow the points' ranges from the body origin, so they change), and a
    sweep-long deskew keeps all four. (Re-binning moved points from the body origin, what the
    front end did, changes the scan; on the real KITTI clip it lost 36 % of the corners.)"""
    box = Polygon(np.array([[2.0, 1.0], [3.0, 1.0], [3.0, 2.0], [2.0, 2.0]]), 1.5, "obstacle")
    points = _scan(_room_world([box]), np.random.default_rng(0))
    config = CornerConfig(max_range_m=20.0)
    chosen, bins = azimuth_scan_indices(points, config)
    scan = np.ascontiguousarray(points[chosen][:, :2])
    before = scan_corners(scan, bins, config)
    assert len(before.points) == 4
    shifted = scan_corners(scan + np.array([0.3, -0.2]), bins, config)
    assert np.allclose(
        shifted.points[:, :2], before.points[:, :2] + np.array([0.3, -0.2]), atol=1e-9
    )
    # what a deskew to the sweep end does to a sensor moving at 3 m/s over a 0.1 s sweep
    sweep_fraction = np.linspace(0.0, 1.0, len(scan))
    moved = scan + np.column_stack([0.3 * (1.0 - sweep_fraction), np.zeros(len(scan))])
    after = scan_corners(moved, bins, config)
    assert len(after.points) == 4
    gaps = np.linalg.norm(after.points[:, None, :2] - before.points[None, :, :2], axis=2)
    assert np.all(gaps.min(axis=1) <= 0.3 + 1e-9)


def test_no_corner_between_shallow_angles_or_along_a_straight_wall():
    # a wall bent by 20 degrees: below the 35-degree minimum, so no corner at the bend
    bent = Polygon(
        np.array(
            [
                [-4.0, -3.0],
                [1.0, -3.0],
                [6.0, -3.0 + 5.0 * np.tan(np.deg2rad(20.0))],
                [6.0, 5.0],
                [-4.0, 5.0],
            ]
        ),
        3.0,
        "boundary",
    )
    points = _scan(World.from_polygons((bent,)), np.random.default_rng(1))
    corners = extract_corners(points, CornerConfig(max_range_m=20.0))
    assert np.min(np.linalg.norm(corners.points[:, :2] - [1.0, -3.0], axis=1)) > 0.5
    bent_loose = extract_corners(points, CornerConfig(max_range_m=20.0, min_corner_angle_deg=15.0))
    assert np.min(np.linalg.norm(bent_loose.points[:, :2] - [1.0, -3.0], axis=1)) < 0.05


def test_occlusion_edges_are_not_corners():
    # a pillar in front of a wall: the wall ends behind it are jump edges, not corners
    pillar = Polygon(np.array([[3.0, -0.3], [3.6, -0.3], [3.6, 0.3], [3.0, 0.3]]), 3.0, "obstacle")
    corners = extract_corners(
        _scan(_room_world([pillar]), np.random.default_rng(2)), CornerConfig(max_range_m=20.0)
    )
    true = np.array([[-4, -3], [6, -3], [6, 5], [-4, 5], [3.0, -0.3], [3.0, 0.3]], dtype=float)
    assert np.all(
        np.linalg.norm(corners.points[:, None, :2] - true[None], axis=2).min(axis=1) < 0.02
    )


def test_split_finds_polyline_vertices():
    s = np.linspace(0, 1, 50)
    polyline = np.concatenate(
        [
            np.column_stack([s, 0 * s]),
            np.column_stack([1 + 0 * s[1:], s[1:]]),
            np.column_stack([1 - s[1:], 1 + 0 * s[1:]]),
        ]
    )
    starts, ends = split_segments(polyline, np.array([0]), np.array([len(polyline) - 1]), 0.05)
    assert list(starts) == [0, 49, 98] and list(ends) == [49, 98, 147]


def test_directions_and_planar_output():
    corners = extract_corners(
        _scan(_room_world(), np.random.default_rng(3)),
        CornerConfig(max_range_m=20.0, directions=True, dimension=2),
    )
    assert corners.points.shape == (4, 2) and corners.directions.shape == (4, 2, 2)
    assert np.allclose(np.linalg.norm(corners.directions, axis=2), 1.0)
    # at the room corner (6, -3) the walls run towards -x and +y
    k = int(np.argmin(np.linalg.norm(corners.points - [6.0, -3.0], axis=1)))
    assert np.allclose(
        sorted(map(tuple, np.round(corners.directions[k], 3))), [(-1.0, 0.0), (0.0, 1.0)], atol=1e-3
    )
    scan = corners.scan(4.0)
    assert scan.t == 4.0 and scan.ids is None and scan.count == 4


def test_covariance_matches_monte_carlo():
    """The first-order covariance of a corner (``corner_covariance`` with the sandwich line
    covariance) against the scatter of corners from 300 noisy scans of the same room.
    Bearing noise is kept small here: it biases the total-least-squares lines (see
    ``extract_corners``), which a covariance cannot describe."""
    config = CornerConfig(
        max_range_m=20.0,
        range_sigma_m=0.03,
        bearing_sigma_rad=0.0005,
        dimension=2,
        split_threshold_m=0.15,
        merge_rms_m=0.06,
        model_sigma_m=0.0,
    )
    world = _room_world()
    rng = np.random.default_rng(4)
    target = np.array([6.0, -3.0])
    samples, predicted = [], []
    for _ in range(300):
        corners = extract_corners(
            _scan(world, rng, config.range_sigma_m, config.bearing_sigma_rad), config
        )
        k = int(np.argmin(np.linalg.norm(corners.points - target, axis=1)))
        assert np.linalg.norm(corners.points[k] - target) < 0.1
        samples.append(corners.points[k])
        predicted.append(corners.covariances[k])
    samples = np.array(samples)
    empirical = np.cov(samples.T)
    mean_predicted = np.mean(predicted, axis=0)
    # per-axis spreads within 20 %, and the normalized errors average near 2 (the dimension);
    # seen: 2.66 for this seed, i.e. the first-order covariance is about 25 % optimistic in
    # some direction (the along-line noise and the split-point choice are not modelled)
    assert np.sqrt(np.diag(mean_predicted)) == pytest.approx(np.sqrt(np.diag(empirical)), rel=0.2)
    errors = samples - target
    nees = np.einsum("ni,nij,nj->n", errors, np.linalg.inv(np.array(predicted)), errors)
    assert 1.6 < nees.mean() < 3.0


def test_bearing_noise_bias_is_small_and_spread_still_predicted():
    """With 2 mrad bearing noise the spread is still predicted; the line bias stays a few mm."""
    config = CornerConfig(
        max_range_m=20.0,
        range_sigma_m=0.03,
        bearing_sigma_rad=0.002,
        dimension=2,
        split_threshold_m=0.15,
        merge_rms_m=0.06,
        model_sigma_m=0.0,
    )
    rng = np.random.default_rng(5)
    target = np.array([6.0, -3.0])
    samples, predicted = [], []
    for _ in range(100):
        corners = extract_corners(
            _scan(_room_world(), rng, config.range_sigma_m, config.bearing_sigma_rad), config
        )
        k = int(np.argmin(np.linalg.norm(corners.points - target, axis=1)))
        samples.append(corners.points[k])
        predicted.append(corners.covariances[k])
    samples = np.array(samples)
    assert np.sqrt(np.diag(np.mean(predicted, axis=0))) == pytest.approx(
        samples.std(axis=0), rel=0.25
    )
    assert np.linalg.norm(samples.mean(axis=0) - target) < 0.006
