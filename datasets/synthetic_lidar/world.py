"""A 2.5-D synthetic lidar world: a corridor loop with alcoves, boxes and pillars.

The world is a set of closed polygons extruded vertically from the floor (z = 0): one
``boundary`` polygon (free space inside: the outer walls of the loop, with alcoves) and
``obstacle`` polygons (free space outside: the inner block of the loop, boxes, square
pillars). Every polygon vertex is a true corner; obstacles never touch each other or the
boundary, so the corners are exactly the vertices. Each corner carries the outward normals
(pointing into free space) of its two faces, which is what a visibility test needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Polygon:
    """A vertical prism.

    Attributes:
        vertices: (m, 2) [m], counter-clockwise.
        height_m: top of the prism above the floor [m].
        kind: ``"boundary"`` (free space inside) or ``"obstacle"`` (free space outside).
    """

    vertices: np.ndarray
    height_m: float
    kind: str

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Edge start and end points, each (m, 2)."""
        return self.vertices, np.roll(self.vertices, -1, axis=0)

    def corner_normals(self) -> np.ndarray:
        """Outward (into free space) unit normals of the two faces at every vertex, (m, 2, 2):
        ``[:, 0]`` of the edge arriving at the vertex, ``[:, 1]`` of the edge leaving it."""
        start, end = self.edges()
        direction = end - start
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        # CCW polygon: the interior lies to the left of each edge.
        left = np.column_stack([-direction[:, 1], direction[:, 0]])
        free = left if self.kind == "boundary" else -left
        arriving = np.roll(free, 1, axis=0)
        return np.stack([arriving, free], axis=1)


@dataclass(frozen=True)
class World:
    """Polygons plus the walls as flat arrays for ray casting.

    Attributes:
        polygons: the prisms.
        wall_start, wall_end: (S, 2) wall segment end points [m].
        wall_height: (S,) wall top [m] (walls start at the floor).
    """

    polygons: tuple[Polygon, ...]
    wall_start: np.ndarray
    wall_end: np.ndarray
    wall_height: np.ndarray

    @staticmethod
    def from_polygons(polygons: tuple[Polygon, ...]) -> World:
        starts, ends, heights = [], [], []
        for polygon in polygons:
            start, end = polygon.edges()
            starts.append(start)
            ends.append(end)
            heights.append(np.full(len(start), polygon.height_m))
        return World(
            polygons, np.concatenate(starts), np.concatenate(ends), np.concatenate(heights)
        )

    def corners(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All corners: positions (K, 2), face normals (K, 2, 2), prism heights (K,)."""
        positions = np.concatenate([polygon.vertices for polygon in self.polygons])
        normals = np.concatenate([polygon.corner_normals() for polygon in self.polygons])
        heights = np.concatenate(
            [np.full(len(polygon.vertices), polygon.height_m) for polygon in self.polygons]
        )
        return positions, normals, heights


def _rectangle(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def _square(cx: float, cy: float, half: float, angle_rad: float = 0.0) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    local = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    return local @ np.array([[c, s], [-s, c]]) + np.array([cx, cy])


def _boundary_with_alcoves() -> np.ndarray:
    """The outer wall of the loop (30 m x 20 m), counter-clockwise, with rectangular alcoves
    (1 m deep) cut into the bottom and top walls: each alcove adds four corners."""
    bottom = [(0.0, 0.0)]
    for x_start in (7.0, 17.0):
        bottom += [(x_start, 0.0), (x_start, -1.0), (x_start + 2.0, -1.0), (x_start + 2.0, 0.0)]
    bottom += [(30.0, 0.0), (30.0, 20.0)]
    top = []
    for x_start in (21.0, 11.0):
        top += [(x_start + 2.0, 20.0), (x_start + 2.0, 21.0), (x_start, 21.0), (x_start, 20.0)]
    top += [(0.0, 20.0)]
    return np.array(bottom + top, dtype=float)


def corridor_world() -> World:
    """The ``lidar-corridor`` world: a 5 m wide rectangular corridor loop around a
    20 m x 10 m inner block, with alcoves, boxes (1.5 m tall, below the 3 m walls) and
    square pillars (0.5 m), all at least 0.5 m from each other and from the walls."""
    polygons = [
        Polygon(_boundary_with_alcoves(), 3.0, "boundary"),
        Polygon(_rectangle(5.0, 5.0, 25.0, 15.0), 3.0, "obstacle"),
        # boxes near the outer wall (corridor centre line is 2.5 m from it)
        Polygon(_rectangle(12.0, 0.5, 13.5, 1.3), 1.5, "obstacle"),
        Polygon(_rectangle(28.7, 8.0, 29.5, 9.2), 1.5, "obstacle"),
        Polygon(_rectangle(15.0, 18.7, 16.2, 19.5), 1.5, "obstacle"),
        Polygon(_rectangle(0.5, 10.5, 1.3, 12.0), 1.5, "obstacle"),
        # pillars between the path and the inner block, one rotated 30 degrees
        Polygon(_square(10.0, 4.2, 0.25), 3.0, "obstacle"),
        Polygon(_square(20.0, 4.2, 0.25, np.deg2rad(30.0)), 3.0, "obstacle"),
        Polygon(_square(25.8, 12.0, 0.25), 3.0, "obstacle"),
        Polygon(_square(8.0, 15.8, 0.25, np.deg2rad(20.0)), 3.0, "obstacle"),
        Polygon(_square(4.2, 8.0, 0.25), 3.0, "obstacle"),
    ]
    return World.from_polygons(tuple(polygons))
