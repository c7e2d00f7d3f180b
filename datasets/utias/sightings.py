"""MRCLAM sightings: barcodes to subjects, the scans of one robot, and the survey labels
its data show swapped (``datasets.utias``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.errors import InputError
from datasets.measurements import LandmarkScan
from datasets.range_bearing import convert
from datasets.rotations import rot2_batch
from datasets.utias.options import UtiasOptions
from datasets.utias.tables import Table, read_table

ROBOT_SUBJECTS = frozenset({1, 2, 3, 4, 5})
"""MRCLAM subjects 1-5 are the robots; their barcodes are not static landmarks."""


def barcode_tables(folder: Path) -> tuple[dict[int, int], dict[int, np.ndarray]]:
    """(barcode -> subject, subject -> surveyed (x, y))."""
    barcodes = read_table(folder / "Barcodes.dat", ("subject", "barcode"))
    subject_of: dict[int, int] = {}
    for (subject, barcode), line in zip(barcodes.values, barcodes.lines):
        if int(barcode) in subject_of:
            raise InputError(f"{barcodes.path}:{line}: barcode {int(barcode)} listed twice")
        subject_of[int(barcode)] = int(subject)
    survey = read_table(
        folder / "Landmark_Groundtruth.dat", ("subject", "x", "y", "x_std", "y_std")
    )
    positions = {int(row[0]): row[1:3].copy() for row in survey.values}
    return subject_of, positions


def build_scans(
    sightings: Table,
    meas_t: np.ndarray,
    span: tuple[float, float],
    subject_of: dict[int, int],
    config: UtiasOptions,
    end_s: float | None = None,
) -> tuple[list[LandmarkScan], tuple[tuple[float, np.ndarray], ...], dict[str, int]]:
    """Group sightings into scans (one per time), dropping what is not a landmark sighting.
    ``span``: the recording's odometry time span (a sighting outside it is dropped and
    counted); ``end_s``: the selected end (``duration_s``: later sightings are not selected,
    which is not a drop)."""
    counts = dict.fromkeys(
        (
            "robot_barcodes",
            "unknown_barcodes",
            "stale_repeats",
            "duplicate_sightings",
            "out_of_range_times",
            "time_going_back",
            "nonpositive_range",
        ),
        0,
    )
    last_seen: dict[int, tuple[float, float]] = {}
    groups: dict[float, dict[int, tuple[float, float]]] = {}
    order: list[float] = []
    latest = -np.inf
    for row, t in zip(sightings.values, meas_t):
        barcode, rng, bearing = int(row[1]), float(row[2]), float(row[3])
        if t < span[0] - 1e-9 or t > span[1] + 1e-9:
            counts["out_of_range_times"] += 1
            continue
        if end_s is not None and t > end_s + 1e-9:
            continue
        if t < latest - 1e-9:
            counts["time_going_back"] += 1
            continue
        latest = max(latest, t)
        subject = subject_of.get(barcode)
        if subject is None:
            counts["unknown_barcodes"] += 1
            continue
        if subject in ROBOT_SUBJECTS:
            counts["robot_barcodes"] += 1
            continue
        if rng <= 0.0:
            counts["nonpositive_range"] += 1
            continue
        if config.drop_stale_repeats and last_seen.get(barcode) == (rng, bearing):
            counts["stale_repeats"] += 1
            continue
        last_seen[barcode] = (rng, bearing)
        key = round(float(t), 9)
        if key not in groups:
            groups[key] = {}
            order.append(key)
        if barcode in groups[key]:
            counts["duplicate_sightings"] += 1
            continue
        groups[key][barcode] = (rng, bearing)
    scans: list[LandmarkScan] = []
    scan_ids: list[tuple[float, np.ndarray]] = []
    for key in order:
        group = groups[key]
        ids = np.array(sorted(group), dtype=int)
        ranges = np.array([group[i][0] for i in ids])
        bearings = np.array([group[i][1] for i in ids])
        sigma_r = np.maximum(config.range_sigma_floor_m, config.range_sigma_fraction * ranges)
        points, covariances = convert(
            ranges, bearings, sigma_r, config.bearing_sigma_rad, config.landmark_conversion
        )
        scans.append(LandmarkScan(t=key, points=points, covariances=covariances, ids=ids))
        scan_ids.append((key, ids))
    return scans, tuple(scan_ids), counts


def detect_label_swaps(
    scans: list[LandmarkScan],
    truth_t: np.ndarray,
    truth_xy: np.ndarray,
    heading: np.ndarray,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
    min_sightings: int = 20,
    tolerance_m: float = 0.5,
) -> list[tuple[int, int]]:
    """Pairs of barcodes whose sightings, placed in the world with the Vicon poses, sit at
    each other's surveyed position (median within ``tolerance_m``) and more than
    ``tolerance_m`` from their own: labels swapped in the survey (MRCLAM dataset 1: 18 and
    61). Barcodes with fewer than ``min_sightings`` sightings are not judged."""
    placed: dict[int, list[np.ndarray]] = {}
    for scan in scans:
        i = min(int(np.searchsorted(truth_t, scan.t)), len(truth_t) - 1)
        rotation = rot2_batch(np.array([heading[i]]))[0]
        for barcode, point in zip(scan.ids, scan.points):
            placed.setdefault(int(barcode), []).append(truth_xy[i] + rotation @ point)
    seen = {
        barcode: np.median(np.array(points), axis=0)
        for barcode, points in placed.items()
        if len(points) >= min_sightings and subject_of.get(barcode) in surveyed
    }
    survey = {barcode: surveyed[subject_of[barcode]] for barcode in seen}
    misplaced = sorted(b for b in seen if np.linalg.norm(seen[b] - survey[b]) > tolerance_m)
    swaps = []
    for index, first in enumerate(misplaced):
        for second in misplaced[index + 1 :]:
            if (
                np.linalg.norm(seen[first] - survey[second]) < tolerance_m
                and np.linalg.norm(seen[second] - survey[first]) < tolerance_m
            ):
                swaps.append((first, second))
    return swaps


def swapped_survey(
    surveyed: dict[int, np.ndarray], subject_of: dict[int, int], swaps: list[tuple[int, int]]
) -> dict[int, np.ndarray]:
    """Surveyed positions by subject with the detected barcode ``swaps`` applied."""
    location = dict(surveyed)
    for first, second in swaps:
        a, b = subject_of[first], subject_of[second]
        location[a], location[b] = surveyed[b], surveyed[a]
    return location
