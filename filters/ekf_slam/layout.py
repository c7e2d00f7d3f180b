"""The EKF-SLAM's vehicle blocks in the joint state vector.

Error-state order (the covariance's order): vehicle first, then landmarks in map order.
Vehicle block: position (d), rotation (1 in 2-D: heading [rad]; 3 in 3-D: a world-frame
rotation error ``R_true = Exp(dphi) R``), then optionally world velocity (d) and gyro bias
(1 or 3). Landmarks: world positions (d each), placed by the filter's
``filters.state_registry.StateRegistry``, which this layout's ``blocks`` feed.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class VehicleLayout:
    """Slices of the vehicle error state.

    Attributes:
        dimension: 2 or 3.
        has_velocity: world-frame velocity in the state (gyro-driven constant-velocity model).
        has_gyro_bias: gyro bias in the state (measured = true + bias).
    """

    dimension: int
    has_velocity: bool
    has_gyro_bias: bool

    @property
    def rotation_size(self) -> int:
        return 1 if self.dimension == 2 else 3

    @property
    def position(self) -> slice:
        return slice(0, self.dimension)

    @property
    def rotation(self) -> slice:
        return slice(self.dimension, self.dimension + self.rotation_size)

    @property
    def velocity(self) -> slice | None:
        if not self.has_velocity:
            return None
        start = self.dimension + self.rotation_size
        return slice(start, start + self.dimension)

    @property
    def gyro_bias(self) -> slice | None:
        if not self.has_gyro_bias:
            return None
        start = self.dimension + self.rotation_size + (self.dimension if self.has_velocity else 0)
        return slice(start, start + self.rotation_size)

    @property
    def size(self) -> int:
        return (
            self.dimension
            + self.rotation_size
            + (self.dimension if self.has_velocity else 0)
            + (self.rotation_size if self.has_gyro_bias else 0)
        )

    def blocks(self) -> list[tuple[str, int]]:
        """(name, size) of the vehicle blocks in state order: the ``StateRegistry``'s
        named vehicle blocks (the slices above are the same, kept for the motion models)."""
        blocks = [("position", self.dimension), ("rotation", self.rotation_size)]
        if self.has_velocity:
            blocks.append(("velocity", self.dimension))
        if self.has_gyro_bias:
            blocks.append(("gyro_bias", self.rotation_size))
        return blocks
