"""Point landmarks: placement, visibility and noisy body-frame observations.

A landmark at world position rho seen from pose (R, r) is at ``p = R^T (rho - r)`` in the
body frame (DESIGN.md). Visibility combines a range window, a horizontal field of view
centred on the body x axis (and a vertical one in 3-D) and, in 2-D, line of sight against
wall segments. Scans with no visible landmark are kept (count 0, arrays of shape (0, d)),
so that estimators see every sensor tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.range_bearing import convert, first_order_covariance

MIN_RANGE_M = 0.5
"""Closer landmarks are not reported (a sensor's blind zone; avoids degenerate bearings)."""

LINE_OF_SIGHT_EPSILON_M = 1e-4
"""A sight line stops this short of its corner, so the corner's own walls do not block it."""


@dataclass(frozen=True)
class ScanSeries:
    """Landmark scans over time.

    Attributes:
        t: scan times [s], shape (S,).
        points: per scan, measured body-frame positions [m], shape (k, d).
        covariances: per scan, stated covariances [m^2], shape (k, d, d).
        ids: per scan, true landmark ids, shape (k,) int.
        directions: per scan, measured unit line directions in the body frame, shape
            (k, j, d), or None when the sensor reports none.
    """

    t: np.ndarray
    points: tuple[np.ndarray, ...]
    covariances: tuple[np.ndarray, ...]
    ids: tuple[np.ndarray, ...]
    directions: tuple[np.ndarray, ...] | None = None

    def visible_counts(self) -> np.ndarray:
        """Landmarks per scan, shape (S,)."""
        return np.array([len(ids) for ids in self.ids], dtype=int)


def to_body_frame(rotation: np.ndarray, position: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """``R^T (rho - r)`` for every landmark: rotation (d, d), position (d,), landmarks (L, d)
    -> (L, d)."""
    return (landmarks - position) @ rotation


def field_of_view_mask(
    body_points: np.ndarray, range_m: float, fov_deg: float, vertical_fov_deg: float | None = None
) -> np.ndarray:
    """Which body-frame points (L, d) lie within [MIN_RANGE_M, range_m], within the
    horizontal field of view ``fov_deg`` centred on the x axis and (3-D) within
    +-vertical_fov_deg/2 of the horizontal plane. Returns a bool mask (L,)."""
    distance = np.linalg.norm(body_points, axis=1)
    mask = (distance >= MIN_RANGE_M) & (distance <= range_m)
    if fov_deg < 360.0:
        azimuth = np.arctan2(body_points[:, 1], body_points[:, 0])
        mask &= np.abs(azimuth) <= np.deg2rad(fov_deg) / 2
    if vertical_fov_deg is not None and body_points.shape[1] == 3:
        elevation = np.arctan2(body_points[:, 2], np.hypot(body_points[:, 0], body_points[:, 1]))
        mask &= np.abs(elevation) <= np.deg2rad(vertical_fov_deg) / 2
    return mask


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def line_of_sight_mask(sensor: np.ndarray, targets: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Which planar targets (L, 2) the sensor (2,) sees past the walls (M, 2, 2).

    A target is hidden when the segment from the sensor to it, shortened by
    ``LINE_OF_SIGHT_EPSILON_M`` at the target end, properly crosses a wall (the two
    segments' end points lie strictly on opposite sides of each other). Grazing contacts
    do not block: a sight line along a wall or through a convex corner sees past it.
    """
    offsets = targets - sensor
    distance = np.linalg.norm(offsets, axis=1, keepdims=True)
    ends = targets - LINE_OF_SIGHT_EPSILON_M * offsets / np.maximum(distance, 1e-12)
    ray = (ends - sensor)[:, None, :]  # (L, 1, 2)
    wall_start, wall_end = walls[None, :, 0, :], walls[None, :, 1, :]
    wall_direction = wall_end - wall_start  # (1, M, 2)
    # Sides of the wall's end points relative to the ray, and of the ray's relative to the wall.
    side_start = _cross(ray, wall_start - sensor)
    side_end = _cross(ray, wall_end - sensor)
    side_sensor = _cross(wall_direction, sensor - wall_start)
    side_target = _cross(wall_direction, ends[:, None, :] - wall_start)
    crosses = (side_start * side_end < 0) & (side_sensor * side_target < 0)
    return ~np.any(crosses, axis=1)


def isotropic_observations(
    body_points: np.ndarray,
    sigmas_m: np.ndarray,
    noise_scale: float,
    stated_scale: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy positions ``p + noise_scale sigma_i n`` (n ~ N(0, I)) and stated covariances
    ``(stated_scale sigma_i)^2 I``. body_points (k, d), sigmas_m (k,) -> ((k, d), (k, d, d))."""
    count, dimension = body_points.shape
    noise = rng.standard_normal((count, dimension)) * (noise_scale * sigmas_m)[:, None]
    covariances = (stated_scale * sigmas_m)[:, None, None] ** 2 * np.eye(dimension)[None]
    return body_points + noise, covariances


@dataclass(frozen=True)
class RangeBearingNoise:
    """A planar laser's range/bearing noise (independent, Gaussian).

    Attributes:
        bearing_sigma_rad: sigma_alpha.
        near_range_sigma_m: sigma_rho for ranges <= switch_range_m.
        far_range_sigma_m: sigma_rho beyond.
        switch_range_m: where the range sigma changes.
    """

    bearing_sigma_rad: float
    near_range_sigma_m: float
    far_range_sigma_m: float
    switch_range_m: float = 10.0

    def range_sigma(self, ranges_m: np.ndarray) -> np.ndarray:
        """sigma_rho for each range (k,) [m]."""
        return np.where(
            ranges_m <= self.switch_range_m, self.near_range_sigma_m, self.far_range_sigma_m
        )


PAPER_LASER = RangeBearingNoise(float(np.deg2rad(3.75)), 0.15, 0.25)
"""Guerreiro et al. (2013), section V: the *filter's* tuning for its Hokuyo (sigma_alpha =
3.75 deg, sigma_rho = 0.15 m up to 10 m, 0.25 m beyond): conservative, not the laser's own
noise."""

UTM_30LX = RangeBearingNoise(float(np.deg2rad(0.25)), 0.03, 0.05)
"""A Hokuyo UTM-30LX-class laser's own noise: the manufacturer's accuracy, +-30 mm from 0.1
to 10 m and +-50 mm from 10 to 30 m, taken as one sigma, and its 0.25 deg angular
resolution as the bearing sigma of a corner (Hokuyo UTM-30LX specification sheet)."""


def range_bearing_observations(
    body_points: np.ndarray,
    noise: RangeBearingNoise,
    noise_scale: float,
    stated_scale: float,
    rng: np.random.Generator,
    drawn_in: str = "polar",
    conversion: str = "unbiased",
) -> tuple[np.ndarray, np.ndarray]:
    """Planar laser observations of body-frame points (k, 2): ((k, 2) points, (k, 2, 2)
    stated covariances).

    ``drawn_in="polar"``: noise drawn in range and bearing (the laser), converted to body
    coordinates by ``conversion`` (``datasets.range_bearing``: the unbiased converted
    measurement, or the plain one with its first-order covariance), the covariance
    evaluated at the measured range and bearing (the paper linearises at the measured
    values). ``drawn_in="cartesian"``: noise drawn from N(0, C) with C the first-order
    covariance at the true range and bearing, stated as C (exactly the model a Cartesian
    estimator assumes: for calibration).
    """
    ranges = np.linalg.norm(body_points, axis=1)
    bearings = np.arctan2(body_points[:, 1], body_points[:, 0])
    if drawn_in == "cartesian":
        covariances = first_order_covariance(
            ranges,
            bearings,
            stated_scale * noise.range_sigma(ranges),
            stated_scale * noise.bearing_sigma_rad,
        )
        drawn = first_order_covariance(
            ranges,
            bearings,
            noise_scale * noise.range_sigma(ranges),
            noise_scale * noise.bearing_sigma_rad,
        )
        factors = np.linalg.cholesky(drawn + 1e-18 * np.eye(2))
        return body_points + np.einsum(
            "kij,kj->ki", factors, rng.standard_normal(body_points.shape)
        ), covariances
    range_sigma = noise.range_sigma(ranges)
    measured_ranges = ranges + noise_scale * range_sigma * rng.standard_normal(len(ranges))
    measured_bearings = bearings + noise_scale * noise.bearing_sigma_rad * rng.standard_normal(
        len(ranges)
    )
    # The conversion debiases with the noise actually drawn (noise-free data stay exact);
    # the covariance is the stated one (equal to the drawn one unless noise_scale=0).
    points, _ = convert(
        measured_ranges,
        measured_bearings,
        noise_scale * noise.range_sigma(measured_ranges),
        noise_scale * noise.bearing_sigma_rad,
        conversion,
    )
    _, covariances = convert(
        measured_ranges,
        measured_bearings,
        stated_scale * noise.range_sigma(measured_ranges),
        stated_scale * noise.bearing_sigma_rad,
        conversion,
    )
    return points, covariances


def planar_direction_observations(
    body_directions: np.ndarray, sigma_rad: float, noise_scale: float, rng: np.random.Generator
) -> np.ndarray:
    """Unit planar directions (k, j, 2) each rotated by an independent N(0, (noise_scale
    sigma)^2) angle (a line fit's orientation error)."""
    angles = noise_scale * sigma_rad * rng.standard_normal(body_directions.shape[:2])
    cos, sin = np.cos(angles), np.sin(angles)
    x, y = body_directions[..., 0], body_directions[..., 1]
    return np.stack([cos * x - sin * y, sin * x + cos * y], axis=-1)


def anchor_order(
    positions: np.ndarray, visible_first: np.ndarray, origin: np.ndarray
) -> np.ndarray:
    """Indices of landmarks ordered for use as anchors.

    The landmarks visible at the start (``visible_first``, bool (L,)) come first: the pair
    farthest apart, then the one making the largest triangle with them (so the first three
    are as far from collinear as the start allows), then the other visible ones by distance
    from ``origin``; then every other landmark by distance from ``origin``.
    positions (L, d) -> permutation (L,).
    """
    visible = np.flatnonzero(visible_first)
    hidden = np.flatnonzero(~visible_first)

    def by_distance(indices: np.ndarray) -> np.ndarray:
        return indices[
            np.argsort(np.linalg.norm(positions[indices] - origin, axis=1), kind="stable")
        ]

    head: list[int] = []
    if len(visible) >= 2:
        points = positions[visible]
        separation = np.linalg.norm(points[:, None] - points[None], axis=2)
        first, second = np.unravel_index(np.argmax(separation), separation.shape)
        head = [int(visible[first]), int(visible[second])]
        if len(visible) >= 3:
            edge = positions[head[1]] - positions[head[0]]
            offsets = points - positions[head[0]]
            if positions.shape[1] == 3:
                areas = np.linalg.norm(np.cross(edge, offsets), axis=1)
            else:
                areas = np.abs(edge[0] * offsets[:, 1] - edge[1] * offsets[:, 0])
            head.append(int(visible[np.argmax(areas)]))
    rest_visible = by_distance(
        np.array([index for index in visible if index not in head], dtype=int)
    )
    return np.concatenate([np.array(head, dtype=int), rest_visible, by_distance(hidden)]).astype(
        int
    )
