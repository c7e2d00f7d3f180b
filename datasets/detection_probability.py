"""How often a landmark sensor sights a landmark inside its view: the model a loader states
and the fit against a reference.

A multi-hypothesis tracker scores a history of association decisions by the likelihood of
the sightings *and* of the landmarks it predicts in view but that went unsighted (Reid
1979, eq. 16: ``log P_D`` for each detected landmark, ``log(1 - P_D)`` for each missed one).
The term is what makes a map with a duplicate landmark pay: each scan that sights one copy
leaves the other copy in view and unsighted. How often a landmark is sighted depends on the
sensor: on UTIAS dataset 1 the camera reads a barcode within 1-3 m in 0.49-0.76 of the
scans where it is in view, beyond 5 m in 0.14-0.26 (robots 1-5, against Vicon and the
surveyed map), so one constant misprices near and far landmarks alike.

The model (``DetectionProbability``): ``P_D`` by the predicted range, piecewise constant on
range bins, inside the sensor's stated view (``NoiseSpec.landmark_field_of_view_deg`` and
``landmark_range_m``). The fit (``fit_detection_probability``): for every scan, the
reference pose's landmarks inside that view, and in each bin the fraction of them the scan
sighted, ``(sighted + 1) / (in view + 2)`` (Laplace's rule: never 0 or 1, so neither term is
ever infinite). Only scans with at least one sighting exist in a dataset that lists
sightings, so the fit, like its use, is conditioned on a scan having happened.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError
from datasets.rotations import rot2_batch


@dataclass(frozen=True)
class DetectionProbability:
    """``P_D`` of a landmark in view, by its range from the sensor.

    Attributes:
        range_edges_m: (B - 1,) increasing inner bin edges [m]; bin b holds ranges in
            ``[edges[b - 1], edges[b])`` (the first from 0, the last to infinity).
        probability: (B,) ``P_D`` per bin, each in (0, 1).
        source: how it was obtained (printed with the run).
        counts: (B,) landmarks in view per bin behind the fit (empty when not fitted).
    """

    range_edges_m: tuple[float, ...]
    probability: tuple[float, ...]
    source: str
    counts: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        edges = np.asarray(self.range_edges_m, dtype=float)
        probability = np.asarray(self.probability, dtype=float)
        if len(probability) != len(edges) + 1:
            raise InputError(
                f"detection probability: {len(probability)} values for {len(edges) + 1} range bins"
            )
        if np.any(np.diff(edges) <= 0) or not np.all((probability > 0) & (probability < 1)):
            raise InputError(
                "detection probability: range edges must increase and every P_D lie in (0, 1)"
            )

    def at(self, ranges_m: np.ndarray) -> np.ndarray:
        """``P_D`` at ``ranges_m`` (n,) [m], shape (n,)."""
        bins = np.searchsorted(np.asarray(self.range_edges_m), np.asarray(ranges_m), side="right")
        return np.asarray(self.probability)[bins]

    def as_dict(self) -> dict:
        return {
            "range_edges_m": [round(edge, 3) for edge in self.range_edges_m],
            "probability": [round(p, 4) for p in self.probability],
            "counts": list(self.counts),
            "source": self.source,
        }


def in_view(
    body_points: np.ndarray, field_of_view_deg: float | None, range_m: float | None
) -> np.ndarray:
    """(n,) bool: points (n, 2 or 3) in the sensor's body frame inside its horizontal field
    of view (centred on the x axis) and range; a missing limit does not limit."""
    points = np.asarray(body_points, dtype=float)
    visible = np.ones(len(points), dtype=bool)
    if field_of_view_deg is not None:
        half = np.deg2rad(field_of_view_deg) / 2.0
        visible &= np.abs(np.arctan2(points[:, 1], points[:, 0])) <= half
    if range_m is not None:
        visible &= np.linalg.norm(points, axis=1) <= range_m
    return visible


@dataclass(frozen=True)
class DetectionPart:
    """One recording's evidence for ``fit_detection_probability_pooled``.

    Attributes:
        scans: (time [s], the true ids sighted) of every scan with a sighting.
        reference: (t (N,), positions (N, 2), headings (N,) [rad]) of the planar reference
            trajectory, interpolated to each scan's time.
        landmarks: true id -> world position (2,) [m].
    """

    scans: list[tuple[float, np.ndarray]]
    reference: tuple[np.ndarray, np.ndarray, np.ndarray]
    landmarks: dict[int, np.ndarray]


def fit_detection_probability(
    scans: list[tuple[float, np.ndarray]],
    reference: tuple[np.ndarray, np.ndarray, np.ndarray],
    landmarks: dict[int, np.ndarray],
    field_of_view_deg: float | None,
    range_m: float | None,
    source: str,
    bin_width_m: float = 1.0,
) -> DetectionProbability:
    """Fit ``P_D`` by range (module docstring) from one recording (``DetectionPart`` says
    what the arguments hold); ``field_of_view_deg``, ``range_m``: the sensor's view
    (``NoiseSpec``); ``bin_width_m``: width of the range bins [m], the last bin ends at
    ``range_m``."""
    return fit_detection_probability_pooled(
        [DetectionPart(scans, reference, landmarks)],
        field_of_view_deg,
        range_m,
        source,
        bin_width_m,
    )


def fit_detection_probability_pooled(
    parts: list[DetectionPart],
    field_of_view_deg: float | None,
    range_m: float | None,
    source: str,
    bin_width_m: float = 1.0,
) -> DetectionProbability:
    """Fit ``P_D`` by range over several recordings of the same sensor: the landmarks in
    view and those sighted are counted per range bin over every part, then the ratio."""
    usable = [part for part in parts if part.scans and part.landmarks]
    if not usable:
        raise InputError(f"detection probability: no scans or no landmarks to fit from ({source})")
    reach = range_m if range_m is not None else 10.0 * bin_width_m
    edges = np.arange(bin_width_m, reach, bin_width_m)
    in_view_count = np.zeros(len(edges) + 1)
    sighted_count = np.zeros(len(edges) + 1)
    for part in usable:
        seen, sighted = _counts(part, edges, field_of_view_deg, range_m)
        in_view_count += seen
        sighted_count += sighted
    probability = (sighted_count + 1.0) / (in_view_count + 2.0)
    return DetectionProbability(
        tuple(float(edge) for edge in edges),
        tuple(float(p) for p in probability),
        source,
        tuple(int(n) for n in in_view_count),
    )


def _counts(
    part: DetectionPart,
    edges: np.ndarray,
    field_of_view_deg: float | None,
    range_m: float | None,
) -> tuple[np.ndarray, np.ndarray]:
    """(landmarks in view, of them sighted) per range bin over one part's scans."""
    ids = np.array(sorted(part.landmarks), dtype=int)
    positions = np.array([part.landmarks[int(i)] for i in ids], dtype=float).reshape(-1, 2)
    truth_t, truth_xy, heading = part.reference
    times = np.array([float(t) for t, _ in part.scans])
    position = np.column_stack([np.interp(times, truth_t, truth_xy[:, k]) for k in (0, 1)])
    angle = np.interp(times, truth_t, np.unwrap(heading))
    offset = positions[None, :, :] - position[:, None, :]  # (S, L, 2) world
    body = np.einsum("sji,slj->sli", rot2_batch(angle), offset)  # R^T (l - p)
    visible = in_view(body.reshape(-1, 2), field_of_view_deg, range_m).reshape(body.shape[:2])
    column = {int(landmark): index for index, landmark in enumerate(ids)}
    sighted = np.zeros(visible.shape, dtype=bool)
    for row, (_, seen) in enumerate(part.scans):
        sighted[row, [column[int(i)] for i in np.asarray(seen, int) if int(i) in column]] = True
    bins = np.searchsorted(edges, np.linalg.norm(body, axis=-1)[visible], side="right")
    in_view_count = np.bincount(bins, minlength=len(edges) + 1).astype(float)
    sighted_count = np.bincount(bins, weights=sighted[visible], minlength=len(edges) + 1)
    return in_view_count, sighted_count
