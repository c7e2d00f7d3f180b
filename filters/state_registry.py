"""Where every variable sits in a filter's joint state: one registry for every filter.

The joint state is laid out ``[vehicle blocks | landmark variables]`` (the layout the
Kalman core, ``filters.kalman``, assumes). The vehicle blocks are named (``"position"``,
``"rotation"``, ...) and fixed for a run; the landmark variables come and go. Each landmark
variable carries its own map id and owns one or more contiguous blocks, each with a name and
a size (a world landmark: one ``"position"`` block of d entries; a sensor-based landmark: a
``"position"`` feature and optionally ``"direction"`` features, d entries each). The model
is OpenVINS' ``StateHelper``: variables know their id and size, every update names the
variables it touches, and nobody computes a state index by hand.

The registry holds indices only, never the mean or the covariance: the filter owns those
and changes them with the Kalman core, the registry telling it which rows and columns:

- ``augment(id, blocks)`` appends a variable (after ``kalman.augment`` appended its rows)
  and returns its slice;
- ``marginalize(ids)`` removes variables and returns the state indices kept, with which the
  caller shrinks its mean (``x[keep]``) and covariance (``kalman.marginalize(P, keep)``);
- ``indices(ids)``, ``slice_of(id)``, ``columns(vehicle, ids)`` (the non-zero columns of a
  ``kalman.SparseJacobian``), ``ids`` in state order.

Blocks (a landmark's features) are also addressable one by one, in state order
(``block_owners``, ``block_names``, ``block_indices``): the sensor-based filter keeps
per-feature data (the last measured value, visibility) in arrays parallel to them.

Lookups are vectorised over parallel arrays (rebuilt on every augment and marginalise, which
are rare next to lookups): a scan's update asks for the indices of tens of landmarks.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np


class StateRegistry:
    """Named vehicle blocks and a registry of landmark variables (module docstring).

    Args:
        vehicle_blocks: (name, size) of each vehicle block, in state order; sizes in state
            entries (error-state dimensions).
    """

    def __init__(self, vehicle_blocks: Iterable[tuple[str, int]]) -> None:
        self._vehicle: dict[str, slice] = {}
        start = 0
        for name, size in vehicle_blocks:
            if name in self._vehicle:
                raise ValueError(f"StateRegistry: vehicle block {name!r} named twice")
            self._vehicle[name] = slice(start, start + int(size))
            start += int(size)
        self.vehicle_size = start
        # one entry per landmark block, in state order
        self._block_owner = np.zeros(0, dtype=int)  # map id of the variable owning the block
        self._block_name = np.zeros(0, dtype=str)
        self._block_size = np.zeros(0, dtype=int)
        # one entry per landmark variable, in state order
        self._ids = np.zeros(0, dtype=int)
        self._block_count = np.zeros(0, dtype=int)
        self._rebuild()

    # ------------------------------------------------------------------ derived arrays
    def _rebuild(self) -> None:
        """Starts and lookups from the per-block and per-variable arrays (after an edit)."""
        self._block_start = self.vehicle_size + np.cumsum(self._block_size) - self._block_size
        self._first_block = np.cumsum(self._block_count) - self._block_count
        self._start = self._block_start[self._first_block]
        ends = np.concatenate([[0], np.cumsum(self._block_size)]).astype(int)
        self._size = ends[self._first_block + self._block_count] - ends[self._first_block]
        self._position = {int(landmark_id): k for k, landmark_id in enumerate(self._ids)}
        self._named: dict[str, np.ndarray] = {}  # block name -> (L,) first such block of each
        self._ids.flags.writeable = False

    def copy(self) -> StateRegistry:
        """An independent registry (a filter's branch continues with its own)."""
        copied = StateRegistry.__new__(StateRegistry)
        copied.__dict__.update(self.__dict__)
        copied._vehicle = dict(self._vehicle)
        copied._named = {}
        copied._position = dict(self._position)
        return copied  # the arrays are replaced on every edit, never changed in place

    # ------------------------------------------------------------------ vehicle
    def vehicle(self, name: str) -> slice:
        """Slice of the vehicle block ``name``."""
        return self._vehicle[name]

    def vehicle_indices(self, names: Sequence[str] | None = None) -> np.ndarray:
        """State indices of the named vehicle blocks, in the order named (all: None)."""
        if names is None:
            return np.arange(self.vehicle_size)
        return np.concatenate(
            [np.arange(self._vehicle[name].start, self._vehicle[name].stop) for name in names]
        ).astype(int)

    # ------------------------------------------------------------------ landmarks
    @property
    def size(self) -> int:
        """N, the length of the joint state."""
        return self.vehicle_size + int(self._block_size.sum())

    @property
    def ids(self) -> np.ndarray:
        """Map ids of the landmark variables in state order, (L,) (read-only)."""
        return self._ids

    def __len__(self) -> int:
        return int(self._ids.size)

    def __contains__(self, landmark_id: object) -> bool:
        return landmark_id in self._position

    def order(self, ids: Iterable[int] | np.ndarray) -> np.ndarray:
        """Position of each variable in state order (its index into ``ids``), (n,)."""
        return np.array([self._position[int(i)] for i in np.asarray(ids).ravel()], dtype=int)

    def augment(self, landmark_id: int, blocks: Sequence[tuple[str, int]]) -> slice:
        """Append a landmark variable of the given (name, size) blocks at the end of the
        state (where ``kalman.augment`` put its rows); returns its slice."""
        landmark_id = int(landmark_id)
        if landmark_id in self._position:
            raise ValueError(f"StateRegistry: landmark {landmark_id} is already in the state")
        if not blocks:
            raise ValueError("StateRegistry: a landmark needs at least one block")
        start = self.size
        names = [name for name, _ in blocks]
        sizes = [int(size) for _, size in blocks]
        self._block_owner = np.concatenate([self._block_owner, np.full(len(blocks), landmark_id)])
        self._block_name = np.concatenate([self._block_name, np.array(names, dtype=str)])
        self._block_size = np.concatenate([self._block_size, np.array(sizes, dtype=int)])
        self._ids = np.concatenate([self._ids, [landmark_id]]).astype(int)
        self._block_count = np.concatenate([self._block_count, [len(blocks)]]).astype(int)
        self._rebuild()
        return slice(start, start + sum(sizes))

    def marginalize(self, ids: Iterable[int] | np.ndarray) -> np.ndarray:
        """Remove the landmark variables ``ids`` (those not in the state are ignored);
        returns the state indices kept, in order (the vehicle's, then the kept
        variables'), with which the caller shrinks x and P (``kalman.marginalize``)."""
        drop_ids = np.asarray(list(ids) if not isinstance(ids, np.ndarray) else ids, dtype=int)
        keep_blocks = np.flatnonzero(~np.isin(self._block_owner, drop_ids))
        keep = np.concatenate([np.arange(self.vehicle_size), self.block_indices(keep_blocks)])
        kept = ~np.isin(self._ids, drop_ids)
        self._block_owner = self._block_owner[keep_blocks]
        self._block_name = self._block_name[keep_blocks]
        self._block_size = self._block_size[keep_blocks]
        self._ids = self._ids[kept]
        self._block_count = self._block_count[kept]
        self._rebuild()
        return keep.astype(int)

    def slice_of(self, landmark_id: int, block: str | None = None) -> slice:
        """Slice of variable ``landmark_id`` (all its blocks), or of its first block named
        ``block``."""
        k = self._position[int(landmark_id)]
        if block is None:
            return slice(int(self._start[k]), int(self._start[k] + self._size[k]))
        b = int(self._named_blocks(block)[k])
        if b < 0:
            raise KeyError(f"StateRegistry: landmark {landmark_id} has no {block!r} block")
        start = int(self._block_start[b])
        return slice(start, start + int(self._block_size[b]))

    def indices(self, ids: Iterable[int] | np.ndarray, block: str | None = None) -> np.ndarray:
        """State indices of the variables ``ids`` (all their blocks, or only each one's
        first block named ``block``), concatenated in the order given, (sum of sizes,)."""
        order = self.order(ids)
        if block is None:
            return _ranges(self._start[order], self._size[order])
        blocks = self._named_blocks(block)[order]
        if np.any(blocks < 0):
            raise KeyError(f"StateRegistry: a landmark asked for has no {block!r} block")
        return self.block_indices(blocks)

    def columns(
        self,
        vehicle: Sequence[str] | None,
        ids: Iterable[int] | np.ndarray = (),
        block: str | None = None,
    ) -> np.ndarray:
        """The non-zero columns of a ``kalman.SparseJacobian`` touching the named vehicle
        blocks (all: None; none: ``()``) and then the variables ``ids`` (``indices``)."""
        own = self.vehicle_indices(vehicle) if vehicle is None or len(vehicle) else np.zeros(0)
        return np.concatenate([own, self.indices(ids, block)]).astype(int)

    # ------------------------------------------------------------------ blocks
    @property
    def block_owners(self) -> np.ndarray:
        """Map id owning each landmark block, in state order, (B,)."""
        return self._block_owner

    @property
    def block_names(self) -> np.ndarray:
        """Name of each landmark block, in state order, (B,)."""
        return self._block_name

    def block_indices(self, blocks: np.ndarray) -> np.ndarray:
        """State indices of landmark blocks (positions into ``block_owners``), concatenated
        in the order given."""
        blocks = np.asarray(blocks, dtype=int)
        return _ranges(self._block_start[blocks], self._block_size[blocks])

    def _named_blocks(self, name: str) -> np.ndarray:
        """(L,) the first block named ``name`` of each variable (-1: it has none); cached
        until the next edit."""
        found = self._named.get(name)
        if found is None:
            found = np.full(self._ids.size, -1, dtype=int)
            variable = np.repeat(np.arange(self._ids.size), self._block_count)
            matching = np.flatnonzero(self._block_name == name)
            # reversed, so that the first matching block of a variable is written last
            found[variable[matching][::-1]] = matching[::-1]
            self._named[name] = found
        return found


def _ranges(starts: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """``concatenate([arange(s, s + n) for s, n in zip(starts, sizes)])``, vectorised."""
    starts = np.asarray(starts, dtype=int)
    sizes = np.asarray(sizes, dtype=int)
    if starts.size == 0:
        return np.zeros(0, dtype=int)
    if np.all(sizes == sizes[0]):  # the common case: every landmark the same size
        return (starts[:, None] + np.arange(sizes[0])[None, :]).ravel()
    return np.concatenate([np.arange(s, s + n) for s, n in zip(starts, sizes)]).astype(int)
