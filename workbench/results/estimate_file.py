"""A run folder's ``estimate.npz`` both ways: an ``Estimate`` as flat named arrays, and the
``Estimate`` back (``read_estimate``), so that a run on disk is data, not only figures.

Layout (``FORMAT_VERSION`` 2; version 1, without the frame, snapshot and joint keys, reads
too):

- per history, ``PREFIX`` = "" (causal) or "smoothed_": ``PREFIXpose_t``, ``_positions``,
  ``_rotations``, ``_covariances``; per block (``datasets.state.BlockName``)
  ``PREFIXNAME_t``, ``_values``, ``_covariances``, ``_frame``; the map snapshots
  ``PREFIXmap_K_ids``, ``_positions``, ``_covariances``, ``_t``, ``_frame`` (K = 0, 1, ...);
- ``smoothed_present``: 1 when the estimator has a smoothed history;
- the final map: ``landmarks_ids``, ``_positions``, ``_covariances``, ``_frame``, ``_t``,
  ``_joint_covariance``;
- ``diag_FIELD`` for every array of ``datasets.estimate.Diagnostics``, ``extra_NAME`` for
  its extras; ``timing_t``, ``timing_seconds``, ``timing_finalize_seconds``.

Events and notes live in ``events.json`` beside it. Not kept: the joint covariance of each
map *snapshot* (its size grows with the square of the map at every snapshot: hundreds of MB
on Victoria Park); the map NEES computed from it is in the run's consistency file, and the
final map keeps its joint covariance.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from datasets.errors import InputError, one_line
from datasets.estimate import Diagnostics, Estimate, Event, StepTiming
from datasets.state import BlockName, Frame, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory
from workbench.run_files import ESTIMATE_FILE, EVENTS_FILE

FORMAT_VERSION = 2

DIAGNOSTIC_FIELDS = (
    "nis_t",
    "nis",
    "nis_dof",
    "scan_nis_t",
    "scan_nis",
    "scan_nis_dof",
    "assoc_t",
    "assoc_measurement_index",
    "assoc_landmark_id",
    "assoc_decision",
    "assoc_reason",
    "assoc_inflation",
    "landmark_count_t",
    "landmark_count",
)
OPTIONAL_DIAGNOSTIC_FIELDS = ("assoc_alternatives",)
"""Diagnostics added after estimate files were first written: absent in older files, read
back as empty (not recorded)."""
HISTORY_PREFIXES = ("", "smoothed_")
# What a damaged zip raises while it is read (a CRC mismatch is a BadZipFile).
_ZIP_ERRORS = (ValueError, zipfile.BadZipFile, zlib.error, EOFError)


def _map_arrays(key: str, landmarks: LandmarkMap, joint: bool) -> dict[str, np.ndarray]:
    arrays = {
        f"{key}_ids": landmarks.ids,
        f"{key}_positions": landmarks.positions,
        f"{key}_frame": np.array(str(landmarks.frame)),
        f"{key}_t": np.array(np.nan if landmarks.t is None else landmarks.t),
    }
    if landmarks.covariances is not None:
        arrays[f"{key}_covariances"] = landmarks.covariances
    if joint and landmarks.joint_covariance is not None:
        arrays[f"{key}_joint_covariance"] = landmarks.joint_covariance
    return arrays


def _history_arrays(prefix: str, history: StateHistory | None) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {}
    if history is None:
        return arrays
    if history.pose is not None:
        arrays[f"{prefix}pose_t"] = history.pose.t
        arrays[f"{prefix}pose_positions"] = history.pose.positions
        arrays[f"{prefix}pose_rotations"] = history.pose.rotations
        if history.pose.covariances is not None:
            arrays[f"{prefix}pose_covariances"] = history.pose.covariances
    for name, block in history.blocks.items():
        arrays[f"{prefix}{name}_t"] = block.t
        arrays[f"{prefix}{name}_values"] = block.values
        arrays[f"{prefix}{name}_frame"] = np.array(str(block.frame))
        if block.covariances is not None:
            arrays[f"{prefix}{name}_covariances"] = block.covariances
    for index, snapshot in enumerate(history.landmarks):
        arrays.update(_map_arrays(f"{prefix}map_{index}", snapshot, joint=False))
    return arrays


def estimate_arrays(estimate: Estimate) -> dict[str, np.ndarray]:
    """Everything numeric of an ``Estimate`` as flat named arrays (module docstring)."""
    arrays = {"format_version": np.array(FORMAT_VERSION)}
    arrays.update(_history_arrays("", estimate.causal))
    arrays.update(_history_arrays("smoothed_", estimate.smoothed))
    arrays["smoothed_present"] = np.array(int(estimate.smoothed is not None))
    if estimate.landmarks is not None:
        arrays.update(_map_arrays("landmarks", estimate.landmarks, joint=True))
    diagnostics = estimate.diagnostics
    for field_name in DIAGNOSTIC_FIELDS + OPTIONAL_DIAGNOSTIC_FIELDS:
        arrays[f"diag_{field_name}"] = getattr(diagnostics, field_name)
    for name, values in diagnostics.extras.items():
        arrays[f"extra_{name}"] = values
    if estimate.frame_times is not None:
        arrays["frame_times"] = estimate.frame_times
    if estimate.timing is not None:
        arrays["timing_t"] = estimate.timing.t
        arrays["timing_seconds"] = estimate.timing.seconds
        arrays["timing_finalize_seconds"] = np.array(estimate.timing.finalize_seconds)
    return arrays


def _read_map(data: dict[str, np.ndarray], key: str, default_frame: Frame) -> LandmarkMap:
    t = float(data[f"{key}_t"]) if f"{key}_t" in data else np.nan
    frame = Frame(str(data[f"{key}_frame"])) if f"{key}_frame" in data else default_frame
    return LandmarkMap(
        ids=data[f"{key}_ids"],
        positions=data[f"{key}_positions"],
        covariances=data.get(f"{key}_covariances"),
        frame=frame,
        t=None if np.isnan(t) else t,
        joint_covariance=data.get(f"{key}_joint_covariance"),
    )


def _read_history(data: dict[str, np.ndarray], prefix: str) -> StateHistory:
    pose = None
    if f"{prefix}pose_t" in data:
        pose = Trajectory(
            data[f"{prefix}pose_t"],
            data[f"{prefix}pose_positions"],
            data[f"{prefix}pose_rotations"],
            data.get(f"{prefix}pose_covariances"),
        )
    blocks = {}
    for name in BlockName:
        if f"{prefix}{name}_values" not in data:
            continue
        frame_key = f"{prefix}{name}_frame"
        blocks[name] = StateBlock(
            data[f"{prefix}{name}_t"],
            data[f"{prefix}{name}_values"],
            data.get(f"{prefix}{name}_covariances"),
            # version 1 did not record frames: the interface's per-block defaults
            Frame(str(data[frame_key])) if frame_key in data else StateBlock.frame,
        )
    snapshots = []
    while f"{prefix}map_{len(snapshots)}_ids" in data:
        snapshots.append(_read_map(data, f"{prefix}map_{len(snapshots)}", Frame.WORLD))
    return StateHistory(pose=pose, blocks=blocks, landmarks=tuple(snapshots))


def _read_events(folder: Path) -> tuple[tuple[Event, ...], tuple[str, ...]]:
    path = folder / EVENTS_FILE
    if not path.is_file():
        return (), ()
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: not a readable events file ({error})") from None
    events = tuple(
        Event(
            float(item["t"]),
            str(item["kind"]),
            {key: value for key, value in item.items() if key not in ("t", "kind")},
        )
        for item in content.get("events", [])
    )
    return events, tuple(str(note) for note in content.get("notes", []))


_NUMERIC_SUFFIXES = (
    "_t",
    "_positions",
    "_rotations",
    "_covariances",
    "_joint_covariance",
    "_values",
    "_ids",
    "_seconds",
    "_nis",
    "_dof",
    "_count",
    "_index",
    "_id",
    "_inflation",
)


def _wanted_kinds(name: str) -> str | None:
    """The dtype kinds an array of this name may have (None: any but objects)."""
    if name.endswith("_frame"):
        return "U"
    if name.startswith("extra_") or not name.endswith(_NUMERIC_SUFFIXES):
        return None  # extras and association decisions may be text
    return "biuf"


def _array_headers(path: Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Shape and dtype of every array in an ``.npz``, from the ``.npy`` headers alone (the
    first bytes of each member), each checked against the member's stored size."""
    headers = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    raise InputError(
                        f"{path}: not an estimate file ('{info.filename}' in it is not an array)"
                    )
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    # estimate_arrays writes plain numeric and text arrays: versions 1.0
                    # and 2.0 (3.0 is for unicode field names, which it never writes)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(member)
                    elif version == (2, 0):
                        shape, _, dtype = np.lib.format.read_array_header_2_0(member)
                    else:
                        raise ValueError(f"'{info.filename}' has .npy format {version}")
                    header_bytes = member.tell()
                # a header claiming more than the member holds would have the reader
                # allocate what the file never backs
                if dtype.hasobject or (
                    int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
                    != info.file_size - header_bytes
                ):
                    raise InputError(
                        f"{path}: not an estimate file ('{info.filename[:-4]}' holds "
                        f"{info.file_size - header_bytes} bytes, not the {dtype} array of "
                        f"shape {shape} its header states)"
                    )
                name = info.filename[:-4]
                # frames are text, times and states numbers: a text time column would only
                # fail later, inside a figure
                wanted = _wanted_kinds(name)
                if wanted is not None and dtype.kind not in wanted:
                    raise InputError(f"{path}: not an estimate file ('{name}' is a {dtype} array)")
                headers[name] = (tuple(shape), dtype)
    except _ZIP_ERRORS as error:
        if isinstance(error, InputError):
            raise
        raise InputError(
            f"{path}: not a readable estimate file (not a zip of numpy arrays: {error})"
        ) from None
    return headers


def _check_lengths(path: Path, headers: dict, keys: list[str], what: str) -> None:
    """The arrays ``keys`` (those present) have one length: a row per time of ``what``."""
    present = [key for key in keys if key in headers]
    lengths = {key: headers[key][0][0] if headers[key][0] else None for key in present}
    if len(set(lengths.values())) > 1:
        found = ", ".join(f"{key} {length}" for key, length in lengths.items())
        raise InputError(f"{path}: not an estimate file ({what} arrays differ in length: {found})")


def check_estimate_file(path: str | Path) -> None:
    """``InputError`` naming ``path`` unless it is an ``estimate.npz`` as ``estimate_arrays``
    writes it: a zip of plain numeric or text arrays (no objects), with every diagnostic
    array, each history's companions (``pose_t`` with ``pose_positions`` and
    ``pose_rotations``, a block's ``_t`` with its ``_values``, the timing's three) and one
    length per history. Reads only the array headers, so a report of many runs stays cheap;
    ``read_estimate`` reads the data."""
    path = Path(path)
    headers = _array_headers(path)
    required = [f"diag_{name}" for name in DIAGNOSTIC_FIELDS]
    for prefix in HISTORY_PREFIXES:
        if f"{prefix}pose_t" in headers:
            required += [f"{prefix}pose_positions", f"{prefix}pose_rotations"]
        for name in BlockName:
            if f"{prefix}{name}_values" in headers:
                required.append(f"{prefix}{name}_t")
    if "timing_t" in headers:
        required += ["timing_seconds", "timing_finalize_seconds"]
    if "landmarks_ids" in headers:
        required.append("landmarks_positions")
    missing = [key for key in required if key not in headers]
    if missing:
        raise InputError(f"{path}: not an estimate file (no {', '.join(missing[:3])})")
    for prefix in HISTORY_PREFIXES:
        pose = ["t", "positions", "rotations", "covariances"]
        _check_lengths(path, headers, [f"{prefix}pose_{key}" for key in pose], "pose")
        for name in BlockName:
            block = [f"{prefix}{name}_{key}" for key in ("t", "values", "covariances")]
            _check_lengths(path, headers, block, name)
    _check_lengths(path, headers, ["timing_t", "timing_seconds"], "timing")
    for stem in ("nis", "scan_nis", "landmark_count"):
        _check_lengths(path, headers, [f"diag_{stem}_t", f"diag_{stem}"], stem)


def load_arrays(path: str | Path) -> dict[str, np.ndarray]:
    """Every array of an ``estimate.npz`` after ``check_estimate_file``; ``InputError``
    naming the file when it is not one or its data is damaged."""
    path = Path(path)
    check_estimate_file(path)
    try:
        with np.load(path, allow_pickle=False) as stored:
            return {key: stored[key] for key in stored.files}
    except _ZIP_ERRORS as error:
        raise InputError(f"{path}: not a readable estimate file ({error})") from None


def read_estimate(folder: str | Path) -> Estimate:
    """The ``Estimate`` a run folder holds (``estimate.npz`` and ``events.json``);
    ``InputError`` naming the file when it is missing or not an estimate file."""
    folder = Path(folder)
    path = folder / ESTIMATE_FILE
    if not path.is_file():
        raise InputError(f"{folder}: not a run folder (no {ESTIMATE_FILE})")
    data = load_arrays(path)
    events, notes = _read_events(folder)
    try:
        return _estimate(data, events, notes)
    except InputError:
        raise
    except (ValueError, TypeError) as error:  # arrays of the right names holding nonsense
        raise InputError(f"{path}: not an estimate file ({one_line(error)})") from None


def _estimate(
    data: dict[str, np.ndarray], events: tuple[Event, ...], notes: tuple[str, ...]
) -> Estimate:
    extras = {
        key[len("extra_") :]: value for key, value in data.items() if key.startswith("extra_")
    }
    optional = {
        name: data[f"diag_{name}"] for name in OPTIONAL_DIAGNOSTIC_FIELDS if f"diag_{name}" in data
    }
    diagnostics = Diagnostics(
        **{name: data[f"diag_{name}"] for name in DIAGNOSTIC_FIELDS},
        events=events,
        extras=extras,
        **optional,
    )
    smoothed_present = bool(data.get("smoothed_present", np.array(0)))
    smoothed = _read_history(data, "smoothed_")
    if not smoothed_present and smoothed.pose is None and not smoothed.blocks:
        smoothed = None
    timing = None
    if "timing_t" in data:
        timing = StepTiming(
            data["timing_t"], data["timing_seconds"], float(data["timing_finalize_seconds"])
        )
    return Estimate(
        causal=_read_history(data, ""),
        diagnostics=diagnostics,
        smoothed=smoothed,
        landmarks=_read_map(data, "landmarks", Frame.WORLD) if "landmarks_ids" in data else None,
        timing=timing,
        notes=notes,
        frame_times=data.get("frame_times"),
    )
