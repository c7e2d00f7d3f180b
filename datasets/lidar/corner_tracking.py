"""Corner confirmation and the re-observation check: which corners behave like fixed
landmarks, measured on the recording itself with KISS-ICP's poses.

A corner extractor also finds "corners" that are not fixed points: the outline of a parked
car, or an occlusion edge, gives a corner whose position slides with the viewpoint (on the
real KITTI clip, 10-50 cm from one frame to the next, about 15 % of the detections). An
estimator takes each for a landmark and explains the slide by moving the vehicle.

``CornerTracker`` carries every corner of the previous frame forward in the world frame
(KISS-ICP's pose of each frame) and

- *confirms* a new corner when a corner of the previous frame lies within the chi-square
  gate of their horizontal difference (``confirm_probability``, covariance the sum of the
  two corners'): a fixed corner is found where it was, a sliding one is not. Only
  confirmed corners are emitted, so every corner an estimator sees has been seen twice in
  place: the first sighting of each corner is withheld, and a corner that slides is never
  emitted at all;
- measures the *re-observation NIS*: for a confirmed corner, the horizontal difference
  between its first world position on its track and the current one, against the sum of
  the two covariances (2 dof). Over long baselines this includes KISS-ICP's drift, so a
  per-dof mean near 1 says the corner covariance covers what estimators will see when they
  close on a corner seen seconds earlier.

The horizontal plane only: a 3-D corner's height is the slab's (``corners`` module), the
same in every frame by construction, so its difference says nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2


@dataclass
class _Track:
    first: np.ndarray  # world position (d,) of its first sighting [m]
    first_covariance: np.ndarray  # (d, d) world frame
    last: np.ndarray
    last_covariance: np.ndarray
    sightings: int
    first_frame: int


@dataclass(frozen=True)
class Reobservation:
    """One confirmed corner against the first sighting of its track, horizontally.

    Attributes:
        residual: now minus first, world frame (2,) [m].
        covariance: the two corners' covariances summed (2, 2) [m^2].
        frames: frames between the two sightings.
        frame: the frame of the current sighting (the first is ``frame - frames``).
        lever: the corner relative to the vehicle now, world frame (2,) [m] (a heading
            error of KISS-ICP's moves it perpendicular to this).
    """

    residual: np.ndarray
    covariance: np.ndarray
    frames: int
    lever: np.ndarray
    frame: int


@dataclass
class ReobservationStats:
    """What the tracker saw: corners, confirmed ones, and the re-observation NIS values
    (horizontal, 2 dof each) with the track age (sightings before) of each."""

    corners: int = 0
    confirmed: int = 0
    nis: list[float] = field(default_factory=list)
    ages: list[int] = field(default_factory=list)
    pairs: list[Reobservation] = field(default_factory=list)

    def summary(self) -> dict[str, float | int | None]:
        values = np.asarray(self.nis)
        return {
            "corners_detected": self.corners,
            "corners_confirmed": self.confirmed,
            "reobservation_pairs": int(values.size),
            "reobservation_nis_per_dof": float(values.mean() / 2.0) if values.size else None,
            "reobservation_nis_median_per_dof": float(np.median(values) / 2.0)
            if values.size
            else None,
        }


class CornerTracker:
    """Confirms corners against the previous frame and records re-observation NIS
    (module docstring)."""

    def __init__(self, confirm_probability: float = 0.99) -> None:
        self.gate = float(chi2.ppf(confirm_probability, 2))
        self.tracks: list[_Track] = []
        self.stats = ReobservationStats()
        # the last frame's confirmed corners against their previous-frame sightings,
        # horizontally, world frame: differences (k, 2) [m] and their covariances (k, 2, 2)
        self.step_residuals = np.zeros((0, 2))
        self.step_covariances = np.zeros((0, 2, 2))

    def confirm(
        self,
        frame: int,
        rotation: np.ndarray,
        position: np.ndarray,
        points: np.ndarray,
        covariances: np.ndarray,
    ) -> np.ndarray:
        """Which body-frame corners ``points`` (k, d) with ``covariances`` (k, d, d) of
        frame number ``frame``, seen from the pose ``rotation`` (d, d) / ``position`` (d,), are confirmed: a boolean
        mask (k,). The tracks move on to this frame's corners."""
        world = points @ rotation.T + position
        world_cov = np.einsum("ij,kjl,ml->kim", rotation, covariances, rotation)
        count, tracks = len(points), self.tracks
        confirmed = np.zeros(count, dtype=bool)
        self.step_residuals, self.step_covariances = np.zeros((0, 2)), np.zeros((0, 2, 2))
        new_tracks = [
            _Track(world[j], world_cov[j], world[j], world_cov[j], 1, frame) for j in range(count)
        ]
        if tracks:
            # every corner against every track's last sighting (the gate) and first sighting
            # (the re-observation NIS) in one evaluation: columns i and m + i are track i's
            m = len(tracks)
            sightings = np.array(
                [track.last for track in tracks] + [track.first for track in tracks]
            )
            sighting_covariances = np.array(
                [track.last_covariance for track in tracks]
                + [track.first_covariance for track in tracks]
            )
            distances = _pairwise_mahalanobis_xy(world, world_cov, sightings, sighting_covariances)
            nearest = np.argmin(distances[:, :m], axis=1)
            confirmed = distances[np.arange(count), nearest] <= self.gate
            matched = np.flatnonzero(confirmed)
            last = nearest[matched]
            self.step_residuals = (world[matched] - sightings[last])[:, :2]
            self.step_covariances = (world_cov[matched] + sighting_covariances[last])[:, :2, :2]
            first = m + nearest[matched]
            self.stats.nis.extend(distances[matched, first].tolist())
            residuals = (world[matched] - sightings[first])[:, :2]
            pair_covariances = (world_cov[matched] + sighting_covariances[first])[:, :2, :2]
            levers = (world[matched] - position)[:, :2]
            for k, (j, i) in enumerate(
                zip(matched.tolist(), nearest[matched].tolist(), strict=True)
            ):
                match = tracks[i]
                self.stats.ages.append(match.sightings)
                self.stats.pairs.append(
                    Reobservation(
                        residuals[k],
                        pair_covariances[k],
                        frame - match.first_frame,
                        levers[k],
                        frame,
                    )
                )
                new_tracks[j] = _Track(
                    match.first,
                    match.first_covariance,
                    world[j],
                    world_cov[j],
                    match.sightings + 1,
                    match.first_frame,
                )
        self.tracks = new_tracks
        self.stats.corners += count
        self.stats.confirmed += int(np.count_nonzero(confirmed))
        return confirmed


def _pairwise_mahalanobis_xy(
    points: np.ndarray, covariances: np.ndarray, others: np.ndarray, other_covariances: np.ndarray
) -> np.ndarray:
    """(k, m) squared Mahalanobis distances of the horizontal differences of ``points``
    (k, d) and ``others`` (m, d) [m], under the sums of their covariances (k, d, d) and
    (m, d, d) [m^2]: the closed-form 2x2 inverse, every pair at once."""
    dx = points[:, None, 0] - others[None, :, 0]
    dy = points[:, None, 1] - others[None, :, 1]
    sxx = covariances[:, None, 0, 0] + other_covariances[None, :, 0, 0]
    sxy = covariances[:, None, 0, 1] + other_covariances[None, :, 0, 1]
    syy = covariances[:, None, 1, 1] + other_covariances[None, :, 1, 1]
    return (syy * dx * dx - 2.0 * sxy * dx * dy + sxx * dy * dy) / (sxx * syy - sxy * sxy)
