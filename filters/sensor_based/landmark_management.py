"""Landmark bookkeeping and deletion (Guerreiro et al. 2013, section V, Fig. 5).

The paper deletes a landmark when it is
1. not visible for a long time while it should be in the field of view,
2. intermittently visible in the past, fewer than an acceptable number of times,
3. the maximum number of landmarks is reached: the non-visible landmark with the highest
   uncertainty goes.

"Should be in the field of view" is judged from the filter's own estimate: the predicted
body-frame position lies inside the configured range/field of view *and* is known well
enough (position std below a threshold) for a miss to mean something. The simulator's
line of sight (walls) hides landmarks the geometry alone says are in view, so the miss
count is consecutive misses, reset by any sighting, and the threshold is generous.

A sighting the association declares new becomes a landmark (``create_landmark``: in the
robocentric frame the measurement is the landmark, with its valid line directions), and
after each scan the deletions leave the state (``manage_after_scan``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from filters.sensor_based.directions import direction_covariance
from filters.sensor_based.state import FilterState


@dataclass(frozen=True)
class ManagementPolicy:
    """Deletion thresholds.

    Attributes:
        in_view_range_m: predicted range up to which a landmark "should be seen" [m].
        in_view_min_range_m: below this it is too close to be expected [m].
        field_of_view_deg: horizontal field of view centred on the body x axis [deg].
        in_view_max_sigma_m: only landmarks whose largest position std is below this count
            as "should be seen" [m].
        max_missed_in_view: consecutive scans in view but not associated before deletion.
        min_observations: a landmark seen fewer times than this ...
        probation_s: ... by this age [s] is deleted as intermittent/spurious.
        max_landmarks: cap on landmarks in the state.
    """

    in_view_range_m: float = 5.0
    in_view_min_range_m: float = 0.3
    field_of_view_deg: float = 360.0
    in_view_max_sigma_m: float = 0.5
    max_missed_in_view: int = 100
    min_observations: int = 3
    probation_s: float = 3.0
    max_landmarks: int = 200


@dataclass
class LandmarkRecord:
    """What the manager knows about one map landmark."""

    created_t: float
    last_seen_t: float
    observations: int = 1
    missed_in_view: int = 0


@dataclass
class LandmarkManager:
    """Tracks sightings of every map landmark and decides deletions.

    Attributes:
        policy: thresholds.
        records: map id -> ``LandmarkRecord``.
        deleted: counts of deletions per criterion (``unseen_in_view``, ``intermittent``,
            ``cap``).
    """

    policy: ManagementPolicy
    records: dict[int, LandmarkRecord] = field(default_factory=dict)
    deleted: dict[str, int] = field(
        default_factory=lambda: {"unseen_in_view": 0, "intermittent": 0, "cap": 0}
    )

    def created(self, landmark_id: int, t: float) -> None:
        self.records[landmark_id] = LandmarkRecord(created_t=t, last_seen_t=t)

    def removed(self, landmark_ids: list[int]) -> None:
        for landmark_id in landmark_ids:
            self.records.pop(int(landmark_id), None)

    def recently_seen(self, landmark_ids: np.ndarray, t: float, window_s: float) -> np.ndarray:
        """(L,) bool: seen within ``window_s`` of ``t`` (the paper's current set I_cur)."""
        return np.array(
            [t - self.records[int(i)].last_seen_t <= window_s for i in landmark_ids], dtype=bool
        )

    def in_view(self, positions: np.ndarray, position_covs: np.ndarray) -> np.ndarray:
        """(L,) bool: predicted inside range and field of view, and known well enough."""
        if len(positions) == 0:
            return np.zeros(0, dtype=bool)
        ranges = np.linalg.norm(positions, axis=1)
        bearing = np.degrees(np.abs(np.arctan2(positions[:, 1], positions[:, 0])))
        sigma = np.sqrt(np.linalg.eigvalsh(position_covs)[:, -1])
        return (
            (ranges <= self.policy.in_view_range_m)
            & (ranges >= self.policy.in_view_min_range_m)
            & (bearing <= 0.5 * self.policy.field_of_view_deg)
            & (sigma <= self.policy.in_view_max_sigma_m)
        )

    def after_scan(
        self,
        t: float,
        landmark_ids: np.ndarray,
        seen: np.ndarray,
        positions: np.ndarray,
        position_covs: np.ndarray,
    ) -> list[int]:
        """Update the records after a scan and return the ids to delete (criteria 1-3).

        Args:
            t: scan time [s].
            landmark_ids: (L,) map ids in the state (after new ones were added).
            seen: (L,) bool, associated or created in this scan.
            positions: (L, d) posterior body-frame positions; position_covs: (L, d, d).
        """
        expected = self.in_view(positions, position_covs)
        doomed: list[int] = []
        for landmark_id, was_seen, should_see in zip(landmark_ids, seen, expected):
            record = self.records[int(landmark_id)]
            if was_seen:
                if record.last_seen_t != t:
                    record.observations += 1
                record.last_seen_t = t
                record.missed_in_view = 0
                continue
            if should_see:
                record.missed_in_view += 1
            if record.missed_in_view >= self.policy.max_missed_in_view:
                doomed.append(int(landmark_id))
                self.deleted["unseen_in_view"] += 1
            elif (
                t - record.created_t >= self.policy.probation_s
                and record.observations < self.policy.min_observations
            ):
                doomed.append(int(landmark_id))
                self.deleted["intermittent"] += 1
        remaining = len(landmark_ids) - len(doomed)
        if remaining > self.policy.max_landmarks:
            keep = ~np.isin(landmark_ids, doomed)
            candidates = np.flatnonzero(keep & ~seen)
            uncertainty = np.trace(position_covs[candidates], axis1=1, axis2=2)
            excess = remaining - self.policy.max_landmarks
            for index in candidates[np.argsort(-uncertainty)][:excess]:
                doomed.append(int(landmark_ids[index]))
                self.deleted["cap"] += 1
        return doomed


def create_landmark(
    state: FilterState,
    manager: LandmarkManager,
    direction_sigma_rad: float,
    t: float,
    point: np.ndarray,
    cov: np.ndarray,
    directions: np.ndarray | None,
) -> int:
    """A new landmark from a sighting (its point, covariance and the finite, non-zero line
    directions measured with it); returns its map id."""
    direction_values = direction_covs = None
    if directions is not None:
        valid = [u for u in directions if np.all(np.isfinite(u)) and np.linalg.norm(u) > 0]
        if valid:
            direction_values = [u / np.linalg.norm(u) for u in valid]
            direction_covs = [
                direction_covariance(u, direction_sigma_rad) for u in direction_values
            ]
    landmark_id = state.add_landmark(point, cov, direction_values, direction_covs)
    manager.created(landmark_id, t)
    return landmark_id


def manage_after_scan(
    state: FilterState,
    manager: LandmarkManager,
    source_of: dict[int, int],
    t: float,
    seen_ids: set[int],
) -> None:
    """Update the records after a scan (``seen_ids``: the map ids associated or created in
    it) and remove the landmarks the policy deletes from the state, the records and
    ``source_of``."""
    ids, positions = state.landmark_positions()
    blocks = state.position_blocks()
    doomed = manager.after_scan(t, ids, np.isin(ids, list(seen_ids)), positions, blocks)
    if doomed:
        state.remove_landmarks(doomed)
        manager.removed(doomed)
        for landmark_id in doomed:
            source_of.pop(landmark_id, None)
