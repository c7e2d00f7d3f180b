"""A planar floor plan: wall segments and the wall corners that serve as landmarks.

The ``guerreiro-loop`` building is a rectangle with a central block, leaving a ring of
corridors. Door niches (shallow rectangular recesses) in both corridor walls add convex
and concave corners, as door jambs do in a real building, so a laser usually sees several
corners at once. Every polygon vertex is a corner landmark.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Niche:
    """A rectangular recess in one side of a rectangle.

    Attributes:
        side: 0 bottom, 1 right, 2 top, 3 left (sides walked counterclockwise).
        center_m: distance of its centre from the start of that side (counterclockwise).
        width_m: opening width.
        depth_m: depth, positive outward of the rectangle, negative inward.
    """

    side: int
    center_m: float
    width_m: float
    depth_m: float


def niched_rectangle(
    lower: tuple[float, float], upper: tuple[float, float], niches: list[Niche]
) -> np.ndarray:
    """Counterclockwise polygon vertices (V, 2) of an axis-aligned rectangle with niches."""
    (x0, y0), (x1, y1) = lower, upper
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
    vertices: list[np.ndarray] = []
    for side in range(4):
        start, end = corners[side], corners[(side + 1) % 4]
        along = (end - start) / np.linalg.norm(end - start)
        outward = np.array([along[1], -along[0]])  # right of a counterclockwise walk
        vertices.append(start)
        for niche in sorted((n for n in niches if n.side == side), key=lambda n: n.center_m):
            opening_start = start + (niche.center_m - niche.width_m / 2) * along
            opening_end = start + (niche.center_m + niche.width_m / 2) * along
            vertices += [
                opening_start,
                opening_start + niche.depth_m * outward,
                opening_end + niche.depth_m * outward,
                opening_end,
            ]
    return np.array(vertices)


def polygon_walls(vertices: np.ndarray) -> np.ndarray:
    """Closed polygon (V, 2) -> wall segments (V, 2, 2)."""
    return np.stack([vertices, np.roll(vertices, -1, axis=0)], axis=1)


def polygon_corner_directions(vertices: np.ndarray) -> np.ndarray:
    """Unit directions from each vertex of a closed polygon (V, 2) towards its previous and
    next vertex, shape (V, 2, 2)."""
    to_previous = np.roll(vertices, 1, axis=0) - vertices
    to_next = np.roll(vertices, -1, axis=0) - vertices
    directions = np.stack([to_previous, to_next], axis=1)
    return directions / np.linalg.norm(directions, axis=2, keepdims=True)


@dataclass(frozen=True)
class FloorPlan:
    """Walls and corner landmarks of a building.

    Attributes:
        walls: wall segments [m], shape (M, 2, 2).
        corners: corner positions [m], shape (K, 2); landmark id = row index.
        corner_directions: unit directions (world frame) along the two walls that meet at
            each corner, pointing away from it, shape (K, 2, 2): [previous wall, next wall]
            of the polygon.
        corridor_centerline: the counterclockwise rectangle (4, 2) at corridor mid-width.
    """

    walls: np.ndarray
    corners: np.ndarray
    corner_directions: np.ndarray
    corridor_centerline: np.ndarray


def ring_corridor_building(
    width_m: float = 20.0,
    height_m: float = 8.0,
    corridor_width_m: float = 2.6,
    niche_depth_m: float | None = None,
) -> FloorPlan:
    """A ring corridor around a central block; the corridor centre line is the rectangle
    [0, width] x [0, height]. Niche positions are fixed and deliberately irregular so that
    the corner constellation looks different at every place along the loop.

    ``niche_depth_m`` replaces every niche's depth (0.3-0.45 m by default). The depth is the
    distance between a niche's jamb corner and its back corner, so it sets how far apart
    the closest corners are: at the laser noise of Guerreiro et al. (3.75 deg, 0.15 m) the
    default niches are individually ambiguous, 1 m deep ones (corners >= 0.8 m apart) much
    less so (association difficulty as a knob)."""
    half = corridor_width_m / 2
    outer_width, outer_height = width_m + corridor_width_m, height_m + corridor_width_m
    inner_width, inner_height = width_m - corridor_width_m, height_m - corridor_width_m
    outer_niches = [
        Niche(0, 3.2, 1.0, 0.35),
        Niche(0, 8.1, 1.2, 0.4),
        Niche(0, 14.6, 0.9, 0.3),
        Niche(0, 19.4, 1.1, 0.45),
        Niche(1, 3.0, 1.0, 0.35),
        Niche(1, 7.4, 0.9, 0.3),
        Niche(2, 4.1, 1.1, 0.4),
        Niche(2, 10.2, 0.9, 0.35),
        Niche(2, 16.8, 1.3, 0.3),
        Niche(3, 5.6, 1.0, 0.4),
    ]
    inner_niches = [
        Niche(0, 2.7, 0.9, -0.3),
        Niche(0, 10.9, 1.0, -0.35),
        Niche(0, 14.8, 0.8, -0.3),
        Niche(1, 2.6, 0.9, -0.3),
        Niche(2, 4.4, 1.0, -0.35),
        Niche(2, 12.3, 0.9, -0.3),
        Niche(3, 3.1, 0.8, -0.3),
    ]
    if niche_depth_m is not None:
        if not 0.0 < niche_depth_m <= 1.2:
            raise ValueError(f"niche depth must be in (0, 1.2] m, got {niche_depth_m}")
        outer_niches = [replace(niche, depth_m=niche_depth_m) for niche in outer_niches]
        inner_niches = [replace(niche, depth_m=-niche_depth_m) for niche in inner_niches]
    outer = niched_rectangle(
        (-half, -half), (-half + outer_width, -half + outer_height), outer_niches
    )
    inner = niched_rectangle((half, half), (half + inner_width, half + inner_height), inner_niches)
    centerline = np.array([[0.0, 0.0], [width_m, 0.0], [width_m, height_m], [0.0, height_m]])
    return FloorPlan(
        walls=np.concatenate([polygon_walls(outer), polygon_walls(inner)]),
        corners=np.concatenate([outer, inner]),
        corner_directions=np.concatenate(
            [polygon_corner_directions(outer), polygon_corner_directions(inner)]
        ),
        corridor_centerline=centerline,
    )
