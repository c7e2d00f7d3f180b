"""One association ``Predictor`` for every filter: predicted landmark measurements and their
covariances ``H P H^T`` from a filter's measurement function over its ``StateRegistry``.

A filter says how it sees its candidate landmarks (``LandmarkMeasurement``: the predicted
measurements and the Jacobian blocks with respect to the vehicle blocks and each landmark's
own block, by name and map id); this module turns that into what the association policy
asks for (``filters.association.policy.Predictor``) and into the stacked ``H`` of an update:

- ``individual``: each candidate's own ``H_i P H_i^T`` (n, d, d), from the vehicle block,
  the landmark's block and their cross-covariance only (O(n), never the n d x n d joint:
  the policy gates every landmark of the map with it);
- ``joint``: the stacked ``H P H^T`` (n d, n d) with every correlation, symmetrised (JCBB's
  joint compatibility);
- ``jacobian``: the stacked ``H`` by its non-zero columns (``kalman.SparseJacobian``).

A measurement that *is* the landmark's block (``y_i = x_i``: the sensor-based filter's
robocentric map, ``landmark_jacobian=None``) is a selection: ``H P H^T`` is then a gather
of P's blocks, computed as such (no products, no symmetrisation: the principal blocks of P
as they are).

A landmark whose id the registry does not hold is known, not estimated (an Aghili anchor):
its rows have vehicle columns only.

``blocks_from_joint`` makes ``individual`` read each candidate's block off the joint
instead (``kalman.diagonal_blocks`` of the symmetrised stacked product): the same
quantity, but BLAS sums a product's terms in an order that depends on the matrices'
shapes, so the two differ by round-off (a few 1e-16 relative). The Aghili filter's gates
were always taken off the joint (its map is the anchors and tens of landmarks); it keeps
that algebra so its estimates stay bit-identical (the inflated noise of a sighting outside
the id gate, and so the estimate, depends on the block's last bits).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from filters.kalman import SparseJacobian, diagonal_blocks
from filters.state_registry import StateRegistry


@dataclass(frozen=True)
class LandmarkMeasurement:
    """A filter's linearised measurement of n candidate landmarks.

    Attributes:
        predicted: (n, d) predicted measurements.
        landmarks: (n,) map ids of the landmarks; an id not in the registry is a known
            landmark with no state columns.
        vehicle: names of the vehicle blocks the measurements depend on, in the column
            order of ``vehicle_jacobian`` (None: the whole vehicle; empty: none).
        vehicle_jacobian: (n, d, v') with respect to those blocks (None when no vehicle).
        landmark_jacobian: (n, d, s) with respect to each landmark's block, or None: the
            identity (the measurement is the block itself).
        block: the landmark block measured (``StateRegistry`` block name; None: the whole
            variable).
    """

    predicted: np.ndarray
    landmarks: np.ndarray
    vehicle: Sequence[str] | None = None
    vehicle_jacobian: np.ndarray | None = None
    landmark_jacobian: np.ndarray | None = None
    block: str | None = None

    @property
    def is_selection(self) -> bool:
        """The measurement is each landmark's block itself (no vehicle, identity)."""
        return self.vehicle_jacobian is None and self.landmark_jacobian is None


class LandmarkPredictor:
    """The association ``Predictor`` of any filter (module docstring).

    Args:
        registry: where the filter's variables sit.
        covariance: the filter's P (N, N) (read, not copied: build one per association).
        measure: candidate indices (n,) -> ``LandmarkMeasurement`` of those candidates.
        blocks_from_joint: ``individual`` as the diagonal blocks of ``joint`` (O(n^2) in
            the candidates; module docstring) instead of each candidate's own product.
    """

    def __init__(
        self,
        registry: StateRegistry,
        covariance: np.ndarray,
        measure: Callable[[np.ndarray], LandmarkMeasurement],
        blocks_from_joint: bool = False,
    ) -> None:
        self.registry = registry
        self.covariance = covariance
        self.measure = measure
        self.blocks_from_joint = blocks_from_joint

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(predicted (n, d), ``H_i P H_i^T`` (n, d, d)) of candidates ``indices``."""
        if self.blocks_from_joint:
            predicted, joint = self.joint(indices)
            return predicted, diagonal_blocks(joint, predicted.shape[1])
        found = self.measure(np.asarray(indices, dtype=int))
        P = self.covariance
        if found.is_selection:
            rows = _rows(self.registry, found, np.arange(len(found.landmarks)))
            return found.predicted, P[rows[:, :, None], rows[:, None, :]]
        vehicle = self._vehicle(found)
        vehicle_jac = found.vehicle_jacobian
        own_vehicle = (
            P[vehicle, vehicle] if isinstance(vehicle, slice) else P[np.ix_(vehicle, vehicle)]
        )
        blocks = vehicle_jac @ own_vehicle @ np.swapaxes(vehicle_jac, 1, 2)
        estimated = self._estimated(found)
        if isinstance(estimated, np.ndarray) and estimated.size == 0:
            return found.predicted, blocks
        rows = _rows(self.registry, found, estimated)  # (e, s): each estimated landmark's entries
        cross = P[vehicle][:, rows].transpose(1, 0, 2)  # (e, v', s): cov(vehicle, landmark)
        own = P[rows[:, :, None], rows[:, None, :]]  # (e, s, s)
        landmark_jac = found.landmark_jacobian[estimated]
        landmark_t = np.swapaxes(landmark_jac, 1, 2)
        mixed = vehicle_jac[estimated] @ cross @ landmark_t
        blocks[estimated] = (
            blocks[estimated] + mixed + np.swapaxes(mixed, 1, 2) + landmark_jac @ own @ landmark_t
        )
        return found.predicted, blocks

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(predicted (n, d), the joint ``H P H^T`` (n d, n d)) of candidates ``indices``."""
        found = self.measure(np.asarray(indices, dtype=int))
        if found.is_selection:
            rows = _rows(self.registry, found, np.arange(len(found.landmarks))).ravel()
            return found.predicted, self.covariance[np.ix_(rows, rows)]
        joint = projected_covariance(stacked_jacobian(self.registry, found), self.covariance)
        return found.predicted, 0.5 * (joint + joint.T)

    def jacobian(self, indices: np.ndarray) -> tuple[np.ndarray, SparseJacobian]:
        """(predicted (n, d), the stacked ``H`` (n d rows)) of candidates ``indices``."""
        found = self.measure(np.asarray(indices, dtype=int))
        return found.predicted, stacked_jacobian(self.registry, found)

    # ------------------------------------------------------------------ helpers
    def _vehicle(self, found: LandmarkMeasurement) -> slice | np.ndarray:
        """The vehicle columns, as a slice when contiguous (a view of P, not a gather)."""
        columns = self.registry.vehicle_indices(found.vehicle)
        if columns.size and np.array_equal(columns, np.arange(columns[0], columns[-1] + 1)):
            return slice(int(columns[0]), int(columns[-1]) + 1)
        return columns

    def _estimated(self, found: LandmarkMeasurement) -> slice | np.ndarray:
        """The candidates the registry holds (all of them: ``slice(None)``, no copy)."""
        held = np.array([int(i) in self.registry for i in found.landmarks], dtype=bool)
        return slice(None) if held.all() else np.flatnonzero(held)


def stacked_jacobian(registry: StateRegistry, found: LandmarkMeasurement) -> SparseJacobian:
    """The stacked ``H`` (n d rows) of a measurement by its non-zero columns: the vehicle
    blocks, then each estimated landmark's own (row block i touches the vehicle and its
    own landmark only)."""
    if found.is_selection:
        return SparseJacobian.selection(_rows(registry, found, slice(None)).ravel())
    n, d, v = found.vehicle_jacobian.shape
    estimated = np.flatnonzero([int(i) in registry for i in found.landmarks])
    columns = registry.columns(found.vehicle, found.landmarks[estimated], found.block)
    values = np.zeros((n, d, columns.size))
    values[:, :, :v] = found.vehicle_jacobian
    if estimated.size:
        s = found.landmark_jacobian.shape[2]
        own = v + s * np.arange(estimated.size)[:, None] + np.arange(s)  # (e, s) local
        values[estimated[:, None, None], np.arange(d)[None, :, None], own[:, None, :]] = (
            found.landmark_jacobian[estimated]
        )
    return SparseJacobian(columns, values.reshape(n * d, columns.size))


def projected_covariance(jacobian: SparseJacobian, covariance: np.ndarray) -> np.ndarray:
    """``H P H^T`` (m, m) from the non-zero columns of H only, as the products give it
    (symmetric to round-off only; ``LandmarkPredictor.joint`` symmetrises it)."""
    columns, values = jacobian.columns, jacobian.values
    return values @ covariance[np.ix_(columns, columns)] @ values.T


def _rows(
    registry: StateRegistry, found: LandmarkMeasurement, which: slice | np.ndarray
) -> np.ndarray:
    """(e, s) state indices of the measured block of the landmarks ``which``."""
    ids = found.landmarks[which]
    jacobian = found.landmark_jacobian
    size = found.predicted.shape[1] if jacobian is None else jacobian.shape[2]
    return registry.indices(ids, found.block).reshape(-1, size)
