"""Trajectory file formats: TUM and KITTI (read and write), and atomic file writes.

TUM: one pose a line, ``t x y z qx qy qz qw`` (note: TUM orders the quaternion x, y, z, w;
our interface order is w, x, y, z and the conversion happens here only). Planar
trajectories are written with z = 0 and a rotation about z, so evo reads them.
KITTI: one pose a line, the 12 entries of the top 3x4 of the homogeneous matrix, no time.
Which of the two a file holds is read from its rows (``trajectory_format``), not only from
its name.
"""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np

from datasets.errors import InputError
from datasets.text_files import text_lines
from datasets.trajectory import Trajectory, trajectory_from_homogeneous


def _umask() -> int:
    """The process umask (read by setting it and setting it back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` through a temp file in the same folder and a rename, so a
    killed process never leaves a half-written file that looks whole."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode() if isinstance(data, str) else data
    handle, temp_name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp creates the file 0600; a result file gets the mode the user's umask gives
        os.fchmod(handle, 0o666 & ~_umask())
        with os.fdopen(handle, "wb") as stream:
            stream.write(payload)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temp_name, path)
    except OSError as error:
        Path(temp_name).unlink(missing_ok=True)
        if error.filename is None:  # a failed write or fsync names no file: name ours
            raise OSError(error.errno, error.strerror, str(path)) from error
        raise
    except BaseException:
        Path(temp_name).unlink(missing_ok=True)
        raise
    return path


def _as_spatial(trajectory: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and quaternions (N, 4) wxyz of any trajectory (planar: z=0, yaw)."""
    if trajectory.dimension == 3:
        return trajectory.positions, trajectory.rotations
    half = 0.5 * trajectory.rotations
    quats = np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)], axis=1)
    positions = np.column_stack([trajectory.positions, np.zeros(len(trajectory))])
    return positions, quats


def format_tum(trajectory: Trajectory) -> str:
    """TUM text of a trajectory (full float precision, deterministic)."""
    positions, quats = _as_spatial(trajectory)
    table = np.column_stack([trajectory.t, positions, quats[:, [1, 2, 3, 0]]])
    buffer = io.StringIO()
    np.savetxt(buffer, table, fmt="%.9f", delimiter=" ")
    return buffer.getvalue()


def write_tum(path: str | Path, trajectory: Trajectory) -> Path:
    """Write a TUM file atomically."""
    return write_atomic(path, "# timestamp tx ty tz qx qy qz qw\n" + format_tum(trajectory))


MAX_POSITION_M = 1e7
"""Positions farther than this from the origin are not a trajectory (a corrupted file, or
values of 1e308 that break every alignment): an error, not a number."""


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM file into a 3-D ``Trajectory``.

    Raises ``InputError`` naming the file and line for a missing or non-text file, a
    malformed line, non-finite or absurd values, stamps that do not increase (out of order,
    repeated: evo would pair them as they are and report a wrong number), or a file without
    poses.
    """
    path = Path(path)
    rows = []
    lines = []
    for line_number, line in text_lines(path, "TUM file"):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        fields = stripped.replace(",", " ").split()
        values = _numeric_row(path, line_number, fields, "t x y z qx qy qz qw", (1, 2, 3))
        if rows and values[0] <= rows[-1][0]:
            raise InputError(
                f"{path}:{line_number}: time {values[0]!r} is not after the previous pose's "
                f"{rows[-1][0]!r} (line {lines[-1]}): stamps out of order or repeated"
            )
        rows.append(values)
        lines.append(line_number)
    if not rows:
        raise InputError(f"{path}: no poses in file")
    table = np.array(rows)
    quats = table[:, [7, 4, 5, 6]]
    norms = np.linalg.norm(quats, axis=1)
    if np.any(norms < 1e-9):
        bad = int(np.argmin(norms))
        raise InputError(f"{path}:{lines[bad]}: zero quaternion at pose {bad} (t={table[bad, 0]})")
    return Trajectory(t=table[:, 0], positions=table[:, 1:4], rotations=quats / norms[:, None])


def write_kitti(path: str | Path, trajectory: Trajectory) -> Path:
    """Write KITTI poses (3x4 row-major a line, no time) atomically; planar poses as 3-D."""
    positions, quats = _as_spatial(trajectory)
    spatial = Trajectory(trajectory.t, positions, quats)
    rows = spatial.homogeneous()[:, :3, :].reshape(len(spatial), 12)
    buffer = io.StringIO()
    np.savetxt(buffer, rows, fmt="%.9e", delimiter=" ")
    return write_atomic(path, buffer.getvalue())


def read_kitti(path: str | Path, t: np.ndarray | None = None) -> Trajectory:
    """Read KITTI poses; times are ``t`` if given, else the pose index (s)."""
    path = Path(path)
    rows = []
    for line_number, line in text_lines(path, "KITTI pose file"):
        if not line.strip():
            continue
        values = _numeric_row(path, line_number, line.split(), "3x4 pose", (3, 7, 11), 12)
        rotation = np.array(values).reshape(3, 4)[:, :3]
        if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-3):
            raise InputError(f"{path}:{line_number}: the 3x3 block is not a rotation")
        if np.linalg.det(rotation) < 0:  # orthogonal, but a mirror: no pose has it
            raise InputError(
                f"{path}:{line_number}: the 3x3 block has determinant -1 (a reflection), "
                "not a rotation"
            )
        rows.append(values)
    if not rows:
        raise InputError(f"{path}: no poses in file")
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :] = np.array(rows).reshape(-1, 3, 4)
    times = np.arange(len(rows), dtype=float) if t is None else np.asarray(t, dtype=float)
    if len(times) != len(rows):
        raise InputError(f"{path}: {len(rows)} poses but {len(times)} times")
    return trajectory_from_homogeneous(times, poses)


TUM_ROW = "8 numbers, time first (t x y z qx qy qz qw): a TUM file"
KITTI_ROW = "12 numbers, no time (a 3x4 pose): a KITTI pose file"
_ROWS = {8: ("tum", TUM_ROW), 12: ("kitti", KITTI_ROW)}
_SUFFIXES = {".tum": "tum", ".kitti": "kitti"}


def trajectory_format(path: str | Path) -> str:
    """``"tum"`` or ``"kitti"``: what a trajectory file holds, read from its first pose row
    (comments and blank lines aside), so that a KITTI file is never taken for TUM stamps.

    A ``.tum`` or ``.kitti`` suffix must agree with the rows: ``InputError`` naming the file,
    the line and what its rows look like otherwise. Any other suffix (``.txt``) lets the rows
    decide. A first row of another length is left to the reader the suffix names (TUM unless
    ``.kitti``), which reports the line; so is an empty or unreadable file.
    """
    path = Path(path)
    claimed = _SUFFIXES.get(path.suffix.lower())
    what = {"tum": "TUM file", "kitti": "KITTI pose file"}.get(claimed or "", "trajectory file")
    first = next(
        (
            (number, len(line.replace(",", " ").split()))
            for number, line in text_lines(path, what)
            if line.strip() and not line.lstrip().startswith("#")
        ),
        None,
    )
    if first is None or first[1] not in _ROWS:
        return claimed or "tum"
    content, rows = _ROWS[first[1]]
    if claimed is not None and claimed != content:
        raise InputError(
            f"{path}:{first[0]}: named {path.suffix} but its rows hold {rows}; "
            f"rename it .{content} (or .txt, to let its rows decide)"
        )
    return content


def save_npz_atomic(path: str | Path, arrays: dict[str, np.ndarray]) -> Path:
    """Save arrays to a compressed ``.npz`` atomically."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return write_atomic(path, buffer.getvalue())


def _numeric_row(
    path: Path,
    line_number: int,
    fields: list[str],
    layout: str,
    position_columns: tuple[int, int, int],
    count: int | None = None,
) -> list[float]:
    """One pose line's numbers, checked: ``count`` of them (default: one per name in
    ``layout``), all finite, the position (``position_columns``) within ``MAX_POSITION_M``
    of the origin; ``InputError`` naming the file and line otherwise."""
    expected = len(layout.split()) if count is None else count
    if len(fields) != expected:
        raise InputError(
            f"{path}:{line_number}: expected {expected} numbers ({layout}), got {len(fields)}"
        )
    try:
        values = [float(field) for field in fields]
    except ValueError as error:
        raise InputError(f"{path}:{line_number}: not a number ({error})") from None
    if not np.all(np.isfinite(values)):
        raise InputError(f"{path}:{line_number}: non-finite value")
    if max(abs(values[column]) for column in position_columns) > MAX_POSITION_M:
        raise InputError(
            f"{path}:{line_number}: position beyond {MAX_POSITION_M:g} m from the origin"
        )
    return values
