"""What the UTIAS loader fits, and from which truth (``UtiasOptions.calibration``).

Four models are fitted against a Vicon reference and the surveyed map: the calibration of
the commanded velocities (``datasets.odometry_calibration.fit_scales_pooled``: speed, turn,
speed-turn coupling), the odometry noise model (``fit_odometry_noise``), the time
correlation of the sightings' errors (``datasets.sighting_correlation``) and the camera's
detection probability by range (``datasets.detection_probability``). Where the reference
comes from decides whether the run's score means anything:

- ``other-robots`` (default): the folder's *other* robots, pooled, never the scored one.
  The models describe the robot type and the camera, not one drive, so a fit on four
  robots is a fair prior for the fifth (cross-validation, leave one robot out). A folder
  with no other robot falls back to ``none``, with a warning.
- ``own-truth``: the scored robot's own Vicon, the truth its run is scored against. This
  is tuning on the test set; it stays available to measure what it buys, and every table
  and metrics.json says which calibration a run used.
- ``none``: nothing fitted (commanded velocities, the white odometry noise of the options,
  independent sightings, no detection probability).

An option given as a value (``odometry_turn_scale=1``) is used as given whatever the
source; ``odometry_noise=FILE`` reads a model file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.detection_probability import (
    DetectionPart,
    DetectionProbability,
    fit_detection_probability_pooled,
)
from datasets.errors import InputError
from datasets.measurements import LandmarkScan
from datasets.odometry_calibration import (
    SCALE_BOUNDS,
    Increments,
    Segment,
    build_windows,
    concatenate_windows,
    fit_odometry_noise,
    fit_scales_pooled,
)
from datasets.odometry_noise import OdometryNoiseModel, read_model_file
from datasets.rotations import rot2_batch
from datasets.sighting_correlation import (
    SightingCorrelation,
    fit_sighting_correlation,
    planar_residuals,
)
from datasets.utias.options import UtiasOptions
from datasets.utias.recording import Recording, read_recording, robot_identity, robots_in
from datasets.utias.sightings import (
    ROBOT_SUBJECTS,
    build_scans,
    detect_label_swaps,
    swapped_survey,
)

SCALE_KEYS = ("speed", "turn", "coupling")
NEUTRAL_SCALES = {"speed": 1.0, "turn": 1.0, "coupling": 0.0}


@dataclass(frozen=True)
class Reference:
    """One robot's data a calibration is fitted on: its recording, its whole-recording
    scans (ids kept), and the survey with the label swaps its own data show."""

    recording: Recording
    scans: list[LandmarkScan]
    swaps: list[tuple[int, int]]  # barcode pairs whose survey labels its data show swapped
    location: dict[int, np.ndarray]  # subject -> surveyed (x, y), swaps applied


@dataclass(frozen=True)
class Calibration:
    """The fitted models a run uses, and where they came from.

    Attributes:
        source: ``other-robots``, ``own-truth`` or ``none`` (what was used, after any
            fall-back).
        summary: one line for tables and metrics.json, e.g. "fitted on robots 2, 3, 4, 5
            (not the scored robot 1)".
        scales: speed, turn, coupling, their origin and the fit's residuals (metadata).
        odometry_model: None for the white per-sample noise of the options.
        correlation, detection: None where not fitted.
        warnings: what the user must hear (a fall-back, a factor at its bound).
    """

    source: str
    summary: str
    scales: dict
    odometry_model: OdometryNoiseModel | None
    correlation: SightingCorrelation | None
    detection: DetectionProbability | None
    warnings: tuple[str, ...] = ()


_CACHE_LIMIT = 32
_references: dict[tuple, Reference] = {}
_calibrations: dict[tuple, Calibration] = {}


def _cached(cache: dict, key: tuple, make):
    """``cache[key]``, made once per process (a sweep loads the same folder many times,
    and a calibration pooled over four robots costs seconds); bounded, oldest out first."""
    if key not in cache:
        if len(cache) >= _CACHE_LIMIT:
            del cache[next(iter(cache))]
        cache[key] = make()
    return cache[key]


def _fit_key(config: UtiasOptions) -> tuple:
    """The options that shape a fit (every one but the run's selection and its ids)."""
    fields = config.model_dump(exclude={"ids", "duration_s", "odometry_gap_s"})
    return tuple(sorted((key, repr(value)) for key, value in fields.items()))


def _survey_key(subject_of: dict[int, int], surveyed: dict[int, np.ndarray]) -> tuple:
    return tuple(sorted(subject_of.items())), tuple(
        (subject, tuple(np.asarray(position, float).tolist()))
        for subject, position in sorted(surveyed.items())
    )


def reference_of(
    recording: Recording,
    config: UtiasOptions,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
) -> Reference:
    """``recording`` as a calibration reference (the label swaps detected on its own data;
    cached per process)."""
    key = (
        recording.folder,
        recording.robot,
        recording.identity,
        _fit_key(config),
        _survey_key(subject_of, surveyed),
    )
    return _cached(_references, key, lambda: _reference_of(recording, config, subject_of, surveyed))


def _reference_of(
    recording: Recording,
    config: UtiasOptions,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
) -> Reference:
    span = (float(recording.odo_t[0]), float(recording.odo_t[-1]))
    scans, _, _ = build_scans(recording.sightings, recording.meas_t, span, subject_of, config)
    swaps = (
        detect_label_swaps(scans, *recording.vicon(), subject_of, surveyed)
        if config.fix_swapped_labels
        else []
    )
    return Reference(recording, scans, swaps, swapped_survey(surveyed, subject_of, swaps))


def calibrate(
    scored: Reference,
    config: UtiasOptions,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
    view: tuple[float | None, float | None],
) -> Calibration:
    """The models for a run on ``scored`` (module docstring); ``view``: the camera's field
    of view [deg] and range [m] as the scored robot's own sightings show them. Cached per
    process on the recordings' files and the options that shape the fits."""
    recording = scored.recording
    key = (
        recording.folder,
        recording.robot,
        tuple(
            (robot, robot_identity(recording.folder, robot))
            for robot in robots_in(recording.folder)
        ),
        _fit_key(config),
        _survey_key(subject_of, surveyed),
        view,
    )
    return _cached(
        _calibrations, key, lambda: _calibrate(scored, config, subject_of, surveyed, view)
    )


def _calibrate(
    scored: Reference,
    config: UtiasOptions,
    subject_of: dict[int, int],
    surveyed: dict[int, np.ndarray],
    view: tuple[float | None, float | None],
) -> Calibration:
    source = config.calibration
    warnings: list[str] = []
    recording = scored.recording
    if source == "other-robots":
        others = [robot for robot in robots_in(recording.folder) if robot != recording.robot]
        if not others:
            warnings.append(
                f"calibration=other-robots: {recording.folder} holds no other robot to fit "
                "the odometry calibration, odometry noise, sighting correlation and detection "
                "probability on; nothing is fitted (calibration=none). "
                "--data calibration=own-truth fits them on the scored truth (tuning on the "
                "test set)"
            )
            source = "none"
        else:
            references = [
                reference_of(
                    _recording(config, recording.folder, robot), config, subject_of, surveyed
                )
                for robot in others
            ]
            summary = (
                f"fitted against the Vicon of robot{'s' if len(others) > 1 else ''} "
                f"{', '.join(map(str, others))} of {recording.folder.name} "
                f"(not the scored robot {recording.robot})"
            )
    if source == "own-truth":
        references = [scored]
        summary = (
            f"fitted against the scored robot {recording.robot}'s own Vicon (tuning on the "
            "truth the run is scored against)"
        )
    if source == "none":
        references = []
        summary = "none (commanded velocities, white odometry noise, independent sightings)"
    origin = f"{summary}"
    scales = _scales(config, references, origin)
    warnings.extend(scales.pop("warnings"))
    if source == "other-robots" and "heading_rms_after_deg" in scales:
        warnings.extend(_disagreement(config, scored, scales))
    model = _odometry_model(config, references, scales, origin)
    correlation = _correlation(config, references, subject_of, origin)
    detection = _detection(config, references, subject_of, view, origin)
    return Calibration(source, summary, scales, model, correlation, detection, tuple(warnings))


def _recording(config: UtiasOptions, folder: Path, robot: int) -> Recording:
    return read_recording(
        folder,
        robot,
        config.grid_step_s,
        config.max_dropped_fraction,
        config.max_heading_rate_rad_s,
        config.max_speed_m_s,
    )


def calibrated_odometry(recording: Recording, scales: dict) -> np.ndarray:
    """(n, 2) the recording's (speed [m/s], turn rate [rad/s]) with ``scales`` applied."""
    from datasets.odometry_calibration import speed_factors

    values = recording.odo_values
    return np.column_stack(
        [
            values[:, 0] * speed_factors(values[:, 1], scales["speed"], scales["coupling"]),
            values[:, 1] * scales["turn"],
        ]
    )


def _segment(config: UtiasOptions, recording: Recording, odo_values: np.ndarray) -> Segment:
    """The recording's odometry rows against its Vicon, each increment end paired with the
    nearest truth sample (grid data share the times; printed logs have two clocks)."""
    odo_t = recording.odo_t
    dt = np.diff(odo_t)
    increments = Increments(
        odo_t[1:] + config.odometry_delay_s,
        dt,
        np.column_stack([odo_values[1:, 0] * dt, np.zeros(len(dt)), odo_values[1:, 1] * dt]),
    )
    truth_t, positions, heading = recording.vicon()
    tolerance = 0.5 * float(np.median(np.diff(truth_t))) + 1e-9
    return Segment(increments, truth_t, positions, heading, tolerance)


def _scales(config: UtiasOptions, references: list[Reference], origin: str) -> dict:
    wanted = {
        "speed": config.odometry_speed_scale,
        "turn": config.odometry_turn_scale,
        "coupling": config.odometry_speed_turn_coupling,
    }
    given = {key: float(value) for key, value in wanted.items() if value != "fit"}
    if len(given) == len(wanted):
        return {**given, "source": "given", "warnings": []}
    if not references:
        return {
            **NEUTRAL_SCALES,
            **given,
            "source": "not fitted (calibration=none)",
            "warnings": [],
        }
    segments = [
        _segment(config, reference.recording, reference.recording.odo_values)
        for reference in references
    ]
    fitted = sorted(set(wanted) - set(given))
    try:
        result = fit_scales_pooled(segments, config.odometry_noise_window_s, fixed=given)
    except InputError as error:
        raise InputError(
            f"odometry calibration = fit ({', '.join(fitted)}), {origin}: {error} "
            "(give the factors, e.g. --data odometry_turn_scale=1)"
        ) from None
    held = "".join(f"; {key} given as {value:g}" for key, value in given.items())
    warnings = [
        f"odometry calibration: the fitted {key} factor {getattr(result, key):.4g} lies at its "
        f"bound ({origin}): the odometry or the truth may be mislabelled (columns swapped?)"
        for key in fitted
        if _at_bound(key, getattr(result, key))
    ]
    return {
        "speed": result.speed,
        "turn": result.turn,
        "coupling": result.coupling,
        "source": (
            f"{origin} ({result.windows} windows of {config.odometry_noise_window_s:g} s): "
            f"speed {result.speed:.4f}, turn {result.turn:.4f}, speed-turn coupling "
            f"{result.coupling:.3f} s/rad{held}"
        ),
        "heading_rms_before_deg": float(np.rad2deg(result.heading_rms_before_rad)),
        "heading_rms_after_deg": float(np.rad2deg(result.heading_rms_after_rad)),
        "position_rms_before_m": result.position_rms_before_m,
        "position_rms_after_m": result.position_rms_after_m,
        "warnings": warnings,
    }


DISAGREEMENT_RATIO = 3.0
"""The scored robot's odometry-versus-Vicon residual, calibrated with the other robots'
factors, more than this many times theirs is a warning (``_disagreement``): on UTIAS
dataset 1 the five robots read 0.91-1.11 in heading and 0.90-1.14 in position."""


def _disagreement(config: UtiasOptions, scored: Reference, scales: dict) -> list[str]:
    """A check, not a fit: the scored robot's odometry, calibrated with the factors fitted
    on the other robots, against its own Vicon over the same windows. Odometry and truth of
    one robot that disagree far more than the others' do (columns swapped, another robot's
    file, axes exchanged) would otherwise run to a wrong number without a word."""
    factors = {key: float(scales[key]) for key in SCALE_KEYS}
    segment = _segment(config, scored.recording, scored.recording.odo_values)
    try:
        own = fit_scales_pooled([segment], config.odometry_noise_window_s, fixed=factors)
    except InputError:
        return []  # too short to compare: the run says what it can
    heading = np.rad2deg(own.heading_rms_after_rad) / max(scales["heading_rms_after_deg"], 1e-12)
    position = own.position_rms_after_m / max(scales["position_rms_after_m"], 1e-12)
    scales["scored_to_references_rms_ratio"] = {
        "heading": float(heading),
        "position": float(position),
    }
    if max(heading, position) <= DISAGREEMENT_RATIO:
        return []
    return [
        f"robot {scored.recording.robot}'s odometry and Vicon disagree {heading:.1f}x (heading) "
        f"and {position:.1f}x (position) more than the other robots' do with the same "
        f"calibration (over {own.windows} windows): odometry columns swapped, the truth's "
        "axes exchanged, or another robot's file?"
    ]


def _at_bound(key: str, value: float) -> bool:
    """A fitted factor pinned to the bound of ``fit_scales`` (the coupling's lower bound,
    0, is the natural "no coupling", not a failure)."""
    low, high = SCALE_BOUNDS[key]
    span = high - low
    return (value - low < 1e-3 * span and key != "coupling") or high - value < 1e-3 * span


def _odometry_model(
    config: UtiasOptions, references: list[Reference], scales: dict, origin: str
) -> OdometryNoiseModel | None:
    """``odometry_noise``: white (None), a model file, or fitted on the references'
    odometry calibrated with ``scales``."""
    choice = config.odometry_noise
    if choice == "white" or (choice == "fit" and not references):
        return None
    if choice != "fit":
        return read_model_file(Path(choice))
    windows = []
    for reference in references:
        recording = reference.recording
        segment = _segment(config, recording, calibrated_odometry(recording, scales))
        try:
            windows.append(
                build_windows(
                    segment.increments,
                    segment.reference_t,
                    segment.reference_positions,
                    segment.reference_headings,
                    config.odometry_noise_window_s,
                    tolerance_s=segment.tolerance_s,
                )
            )
        except InputError as error:
            raise InputError(
                f"odometry_noise=fit, {recording.name}: {error} (use --data "
                "odometry_noise=white, or a model file from `workbench calibrate-noise`)"
            ) from None
    fit = fit_odometry_noise(concatenate_windows(windows), "")
    source = (
        f"{origin} ({fit.windows} windows of {config.odometry_noise_window_s:g} s; "
        f"{len(fit.excluded)} outlier windows excluded)"
    )
    return OdometryNoiseModel(fit.model.rates, source)


def _correlation(
    config: UtiasOptions, references: list[Reference], subject_of: dict[int, int], origin: str
) -> SightingCorrelation | None:
    """The sightings' error correlation in time against each reference's Vicon poses
    (interpolated to each sighting) and survey; robots are kept apart (a pair of
    consecutive sightings is one robot's)."""
    if config.sighting_correlation == "none" or not references:
        return None
    times, keys, residuals = [], [], []
    for reference in references:
        if not reference.scans:
            continue  # a robot without sightings has nothing to say about them
        t, barcodes, residual = _sighting_residuals(reference, subject_of)
        times.append(t)
        keys.append(barcodes + 1_000_000 * reference.recording.robot)
        residuals.append(residual)
    count = sum(len(t) for t in times)
    if count == 0:
        return None  # no sighting of a surveyed landmark to fit on
    try:
        return fit_sighting_correlation(
            np.concatenate(times),
            np.concatenate(keys),
            np.concatenate(residuals),
            f"{origin} ({count} sightings)",
        )
    except InputError as error:
        raise InputError(
            f"sighting_correlation=fit, {origin}: {error} (use --data sighting_correlation=none)"
        ) from None


def _sighting_residuals(
    reference: Reference, subject_of: dict[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times (k,), barcodes (k,), (radial, tangential) residuals (k, 2)) of the
    reference's sightings of surveyed landmarks against its Vicon."""
    scans = reference.scans
    truth_t, truth_xy, heading = reference.recording.vicon()
    times = np.concatenate([np.full(len(scan.ids), scan.t) for scan in scans] or [np.zeros(0)])
    barcodes = np.concatenate([np.asarray(scan.ids, int) for scan in scans] or [np.zeros(0, int)])
    points = np.concatenate([scan.points for scan in scans] or [np.zeros((0, 2))])
    location = reference.location
    surveyed = {b: location.get(subject_of.get(int(b), -1)) for b in set(barcodes.tolist())}
    known = np.array([surveyed[int(b)] is not None for b in barcodes], dtype=bool)
    times, barcodes, points = times[known], barcodes[known], points[known]
    landmarks = np.array([surveyed[int(b)] for b in barcodes]).reshape(-1, 2)
    position = np.column_stack([np.interp(times, truth_t, truth_xy[:, k]) for k in (0, 1)])
    rotation = rot2_batch(np.interp(times, truth_t, np.unwrap(heading)))
    predicted = np.einsum("nji,nj->ni", rotation, landmarks - position)  # R^T (l - p)
    return times, barcodes, planar_residuals(points, predicted)


def _detection(
    config: UtiasOptions,
    references: list[Reference],
    subject_of: dict[int, int],
    view: tuple[float | None, float | None],
    origin: str,
) -> DetectionProbability | None:
    """How often the camera sights a barcode in ``view``, by range, against each
    reference's Vicon poses and survey (label swaps applied)."""
    parts = []
    barcode_of = {subject: barcode for barcode, subject in subject_of.items()}
    for reference in references:
        if not reference.scans:
            continue
        landmarks = {
            int(barcode_of[subject]): np.asarray(position, float)
            for subject, position in reference.location.items()
            if subject in barcode_of and subject not in ROBOT_SUBJECTS
        }
        parts.append(
            DetectionPart(
                [(scan.t, np.asarray(scan.ids, int)) for scan in reference.scans],
                reference.recording.vicon(),
                landmarks,
            )
        )
    if config.detection_probability == "none" or not parts:
        return None  # nothing to fit from: a recording without sightings states none
    scans = sum(len(part.scans) for part in parts)
    return fit_detection_probability_pooled(parts, *view, f"{origin} ({scans} scans)")
