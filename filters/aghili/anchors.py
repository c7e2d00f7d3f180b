"""The r anchor landmarks that fix Aghili's map (section 2.1): known world positions that
are not estimated, so the filter's frame is the world frame.

``known`` anchors are the dataset's surveyed positions (the first r of
``Sequence.known_landmarks``); ``first-observation`` anchors are placed from their first
noisy sighting (the paper's choice), which makes the map frame differ from the world frame
by that sighting's error, so NEES against truth is not comparable then.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from datasets.errors import InputError
from datasets.measurements import LandmarkScan
from datasets.sequence import Sequence


class Anchors:
    """The anchors of one run.

    Attributes:
        count: r.
        ids: the anchors' landmark ids (known ids, scan ids, or new ids), length <= r.
        positions: world positions (k, 3) [m]; k = 0 until placed.
        pending: waiting for the first sighting (first-observation mode).
        note: what the run should report about them, or None.
    """

    def __init__(self, count: int, source: str, sequence: Sequence) -> None:
        self.count = count
        self.ids: list[int] = []
        self.positions = np.zeros((0, 3))
        self.pending = False
        self.note: str | None = None
        self.decision: str | None = None  # what anchor_source=auto chose, and why
        known = sequence.known_landmarks
        if source == "auto":
            # decided from what the data offer, and said
            have = 0 if known is None else len(known)
            source = "known" if have >= count else "first-observation"
            self.decision = (
                f"anchors: {count} of the {have} surveyed landmarks {sequence.name} offers"
                if source == "known"
                else f"anchors from their first observation: {sequence.name} offers {have} "
                f"surveyed landmarks, {count} needed (anchor_source=auto)"
            )
        if source == "known":
            if known is None or len(known) < count:
                have = 0 if known is None else len(known)
                raise InputError(
                    f"{sequence.name}: anchors={count} known landmarks requested, the dataset "
                    f"offers {have} (use anchor_source=first-observation)"
                )
            self.ids = [int(i) for i in known.ids[:count]]
            self.positions = np.array(known.positions[:count], dtype=float)
            return
        self.pending = True
        if known is not None and len(known) >= count:
            self.ids = [int(i) for i in known.ids[:count]]
        self.note = (
            "anchors taken from their first noisy observation (paper section 2.1): the map frame "
            "differs from the world frame by the anchors' observation error, so NEES against "
            "truth is not comparable"
        )

    @property
    def placed(self) -> int:
        """Anchors with a position."""
        return len(self.positions)

    def waiting(self, landmark_id: int) -> bool:
        """An anchor's id whose position is not known yet."""
        return self.pending and landmark_id in self.ids

    def place(
        self,
        scan: LandmarkScan,
        attitude: np.ndarray,
        position: np.ndarray,
        new_id: Callable[[], int],
    ) -> None:
        """Section 2.1 alternative: ``rho_j = A p_j(0) + r`` from the first scan that sees
        every anchor (the named ones with ids; otherwise the scan's first r sightings)."""
        points = np.asarray(scan.points, float)
        if self.ids and scan.ids is not None:
            index = {int(i): j for j, i in enumerate(np.asarray(scan.ids, int))}
            if not all(i in index for i in self.ids):
                return  # wait for a scan that sees all of them
            rows = [index[i] for i in self.ids]
        else:
            if len(points) < self.count:
                return
            rows = list(range(self.count))
            if scan.ids is not None:
                self.ids = [int(scan.ids[j]) for j in rows]
            else:
                self.ids = [new_id() for _ in rows]
        self.positions = points[rows] @ attitude.T + position
        self.pending = False
