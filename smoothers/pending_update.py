"""``PendingUpdate``: the factors, new values and key times gathered for the next backend
update (a keyframe's motion, GPS and landmark factors, new landmark variables, anchors).

Key times are what the fixed-lag smoother marginalises by: a variable's time is that of
the latest measurement touching it, so a landmark seen again is kept in the window.
"""

from __future__ import annotations

import gtsam
import numpy as np


class PendingUpdate:
    """What the next backend update will add.

    Attributes:
        graph: the new factors. values: the new variables' initial values.
        times: key -> time [s] of the latest measurement touching it.
    """

    def __init__(self) -> None:
        self.graph = gtsam.NonlinearFactorGraph()
        self.values = gtsam.Values()
        self.times: dict[int, float] = {}

    def add(self, factor: gtsam.NonlinearFactor) -> None:
        self.graph.add(factor)

    def add_graph(self, graph: gtsam.NonlinearFactorGraph) -> None:
        self.graph.push_back(graph)

    def insert(self, values: gtsam.Values, t: float) -> None:
        """New variables, all stamped ``t`` [s]."""
        self.values.insert(values)
        for key in values.keys():
            self.times[key] = float(t)

    def insert_point(self, key: int, position: np.ndarray, t: float) -> None:
        """A new landmark variable at ``position`` (d,) [m], stamped ``t`` [s]."""
        self.values.insert(key, np.asarray(position, dtype=float))
        self.times[key] = float(t)

    def touch(self, key: int, t: float) -> None:
        """A measurement at ``t`` [s] involves ``key``."""
        self.times[key] = float(t)

    def holds(self, key: int) -> bool:
        """Whether ``key`` is a new variable of this update."""
        return self.values.exists(key)

    def empty(self) -> bool:
        return not (self.graph.size() or self.values.size())

    def take(self) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, dict[int, float]]:
        """(graph, values, times), leaving this one empty."""
        taken = self.graph, self.values, self.times
        self.__init__()
        return taken
