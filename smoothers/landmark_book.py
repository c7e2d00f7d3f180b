"""The smoother's map bookkeeping: map ids, their current GTSAM variables, the anchors.

A landmark keeps its map id for the whole run; its *variable* may change: the fixed-lag
smoother marginalises a landmark that left the window, and a later sighting of it starts a
new variable (``l0, l1, ...`` are never reused). Anchors (``sequence.known_landmarks``,
the same ones the filters anchor to) are landmarks with a surveyed position, given a tight
prior each time they get a variable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gtsam.symbol_shorthand import L

from datasets.errors import InputError
from datasets.sequence import Sequence

DEFAULT_ANCHORS_3D = 3
"""Anchors when the dataset offers known landmarks and the config says None (3-D; the
aghili filter's default: three non-collinear landmarks make the frame observable)."""


@dataclass
class MapLandmark:
    """One map landmark: its current variable key and bookkeeping.

    Attributes:
        map_id: the estimator's id (the scan id with ids).
        key: the GTSAM key of its current variable.
        anchor_position: a known landmark's surveyed position (d,) [m], or None.
        observations: sightings used so far. last_t: time of the latest [s].
    """

    map_id: int
    key: int
    anchor_position: np.ndarray | None = None
    observations: int = 0
    last_t: float = 0.0


class LandmarkBook:
    """The map: map id -> ``MapLandmark``, with fresh GTSAM keys ``l0, l1, ...``."""

    def __init__(self) -> None:
        self.landmarks: dict[int, MapLandmark] = {}
        self.next_map_id = 0
        self._next_key_index = 0

    def variable(self, map_id: int, t: float) -> MapLandmark:
        """The landmark ``map_id`` with a new variable key (created when unknown)."""
        key = L(self._next_key_index)
        self._next_key_index += 1
        landmark = self.landmarks.get(map_id)
        if landmark is None:
            landmark = MapLandmark(map_id=map_id, key=key)
            self.landmarks[map_id] = landmark
            self.next_map_id = max(self.next_map_id, map_id + 1)
        else:
            landmark.key = key
        landmark.last_t = float(t)
        return landmark

    def new_map_id(self) -> int:
        """An id no landmark has (geometric association: the map numbers its landmarks)."""
        map_id = self.next_map_id
        self.next_map_id += 1
        return map_id

    def sorted(self) -> list[MapLandmark]:
        """Every landmark, by map id."""
        return sorted(self.landmarks.values(), key=lambda landmark: landmark.map_id)


def anchor_landmarks(
    count: int | None, sequence: Sequence, dimension: int
) -> list[tuple[int, np.ndarray]]:
    """(map id, surveyed position (d,) [m]) of the first ``count`` known landmarks (None:
    ``DEFAULT_ANCHORS_3D`` in 3-D when the dataset offers them, else none)."""
    known = sequence.known_landmarks
    if count is None:
        count = DEFAULT_ANCHORS_3D if known is not None and dimension == 3 else 0
    if count == 0:
        return []
    if known is None or len(known) < count:
        have = 0 if known is None else len(known)
        raise InputError(
            f"{sequence.name}: anchors={count} but the dataset offers {have} known landmarks"
        )
    if known.dimension != dimension:
        raise InputError(
            f"{sequence.name}: known landmarks are {known.dimension}-D, the sequence is {dimension}-D"
        )
    return [
        (int(known.ids[index]), np.asarray(known.positions[index], dtype=float))
        for index in range(count)
    ]
