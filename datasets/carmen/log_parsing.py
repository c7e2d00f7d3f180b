"""Reading a CARMEN ``.clf`` log (plain or bzip2-compressed) into typed messages.

Every line is one message (``datasets.carmen.messages`` gives the formats). Lines starting
with ``#`` are comments; message types other than the lasers, ``ODOM`` and ``PARAM`` (``SYNC``,
``TRUEPOS``, ``NMEA-GGA``, ``RAWLASER1`` and the like) are skipped and counted by type. A laser
or odometry line that does not parse (too few fields, a word where a number belongs, a
reading that is not finite) is an ``InputError`` naming the file, the line and the field:
a log is not silently shortened.
"""

from __future__ import annotations

import bz2
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from datasets.carmen.messages import (
    NO_RETURN_RANGE_M,
    LaserMessage,
    OdometryMessage,
    Parameter,
    guessed_angle_step_rad,
)
from datasets.errors import InputError
from datasets.text_files import check_regular_file

BZIP2_MAGIC = b"BZh"


@dataclass
class ParsedLog:
    """The messages of one log, in file order.

    Attributes:
        path: the file.
        lasers: every laser line (front and rear).
        odometry: every ``ODOM`` line.
        parameters: ``PARAM`` name -> its last value (a later line overrides an earlier one,
            as CARMEN's parameter server does).
        skipped: message type -> number of lines skipped (not used by the loader).
        comments: number of comment lines.
    """

    path: Path
    lasers: list[LaserMessage] = field(default_factory=list)
    odometry: list[OdometryMessage] = field(default_factory=list)
    parameters: dict[str, Parameter] = field(default_factory=dict)
    skipped: Counter = field(default_factory=Counter)
    comments: int = 0


def log_text(path: Path) -> str:
    """The text of a ``.clf`` file, decompressed when it is bzip2 (by its magic bytes, not
    its name); ``InputError`` naming the file when it cannot be read or decoded."""
    path = check_regular_file(Path(path), "CARMEN log")
    try:
        data = path.read_bytes()
        if data.startswith(BZIP2_MAGIC):
            data = bz2.decompress(data)
    except OSError as error:
        raise InputError(f"{path}: cannot be read ({error})") from None
    try:
        return data.decode("ascii")
    except UnicodeDecodeError as error:
        raise InputError(
            f"{path}: not a CARMEN text log (byte {error.start} is 0x{data[error.start]:02x})"
        ) from None


def _numbers(path: Path, number: int, tag: str, words: list[str], what: str) -> np.ndarray:
    """``words`` as floats; ``InputError`` naming the first word that is not a finite number."""
    try:
        values = np.array(words, dtype=float)
    except ValueError:
        values = None
    if values is None or not np.all(np.isfinite(values)):
        for offset, word in enumerate(words):
            try:
                if np.isfinite(float(word)):
                    continue
            except ValueError:
                pass
            raise InputError(
                f"{path}:{number}: {tag} {what} field {offset + 1} is '{word}', not a finite number"
            ) from None
    return values


def _count(path: Path, number: int, tag: str, word: str, what: str) -> int:
    try:
        value = int(word)
    except ValueError:
        raise InputError(f"{path}:{number}: {tag} {what} is '{word}', not an integer") from None
    if value < 0:
        raise InputError(f"{path}:{number}: {tag} {what} is {value}, below 0")
    return value


def _need(path: Path, number: int, tag: str, words: list[str], count: int, layout: str) -> None:
    if len(words) < count:
        raise InputError(
            f"{path}:{number}: {tag} has {len(words) - 1} fields after the tag, needs at least "
            f"{count - 1} ({layout})"
        )


def _stamp(path: Path, number: int, tag: str, word: str) -> str:
    try:
        value = float(word)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value) or value < 0:
        raise InputError(f"{path}:{number}: {tag} ipc_timestamp is '{word}', not a time [s]")
    return word


def parse_old_laser(path: Path, number: int, words: list[str]) -> LaserMessage:
    """An ``FLASER``/``RLASER`` line: ``TAG n r_1..r_n x y theta odom_x odom_y odom_theta
    ipc_timestamp [ipc_hostname logger_timestamp]``."""
    tag = words[0]
    _need(path, number, tag, words, 2, "num_readings")
    beams = _count(path, number, tag, words[1], "num_readings")
    layout = f"{beams} ranges, x y theta, odom_x odom_y odom_theta, ipc_timestamp"
    _need(path, number, tag, words, beams + 9, layout)
    ranges = _numbers(path, number, tag, words[2 : 2 + beams], "range")
    poses = _numbers(path, number, tag, words[2 + beams : 8 + beams], "pose")
    return LaserMessage(
        kind=tag,
        line=number,
        stamp=_stamp(path, number, tag, words[8 + beams]),
        ranges=ranges,
        start_angle_rad=float(-np.pi / 2.0),
        angle_step_rad=guessed_angle_step_rad(beams),
        max_range_m=NO_RETURN_RANGE_M,
        odometry=poses[3:6],
        logged_pose=poses[0:3],
    )


def parse_robot_laser(path: Path, number: int, words: list[str]) -> LaserMessage:
    """A ``ROBOTLASER1`` line (``datasets.carmen.messages``)."""
    tag = words[0]
    _need(path, number, tag, words, 9, "laser_type .. num_readings")
    config = _numbers(path, number, tag, words[2:7], "configuration")
    start, _, step, max_range, _ = config
    beams = _count(path, number, tag, words[8], "num_readings")
    _need(path, number, tag, words, 10 + beams, f"{beams} ranges, num_remissions")
    ranges = _numbers(path, number, tag, words[9 : 9 + beams], "range")
    remissions = _count(path, number, tag, words[9 + beams], "num_remissions")
    at = 10 + beams + remissions
    _need(
        path,
        number,
        tag,
        words,
        at + 12,
        "remissions, laser pose, robot pose, tv rv forward_safety side_safety turn_axis, ipc_timestamp",
    )
    poses = _numbers(path, number, tag, words[at : at + 6], "pose")
    if step <= 0:
        raise InputError(f"{path}:{number}: {tag} angular_resolution is {step}, not above 0")
    laser, robot = poses[0:3], poses[3:6]
    cos, sin = np.cos(robot[2]), np.sin(robot[2])
    delta = laser[:2] - robot[:2]
    mounting = np.array(
        [
            cos * delta[0] + sin * delta[1],
            -sin * delta[0] + cos * delta[1],
            float(np.angle(np.exp(1j * (laser[2] - robot[2])))),
        ]
    )
    return LaserMessage(
        kind=tag,
        line=number,
        stamp=_stamp(path, number, tag, words[at + 11]),
        ranges=ranges,
        start_angle_rad=float(start),
        angle_step_rad=float(step),
        max_range_m=float(max_range) if max_range > 0 else NO_RETURN_RANGE_M,
        odometry=robot,
        logged_pose=laser,
        mounting=mounting,
    )


def parse_odometry(path: Path, number: int, words: list[str]) -> OdometryMessage:
    """An ``ODOM x y theta tv rv accel ipc_timestamp ..`` line."""
    _need(path, number, "ODOM", words, 8, "x y theta tv rv accel ipc_timestamp")
    values = _numbers(path, number, "ODOM", words[1:7], "pose/velocity")
    return OdometryMessage(
        line=number,
        stamp=_stamp(path, number, "ODOM", words[7]),
        pose=values[0:3],
        velocity=values[3:5],
    )


def _bulk(
    path: Path, rows: list[tuple[int, list[str]]], first: int, last: int
) -> np.ndarray | None:
    """The fields ``[first, last)`` of every row as one float array (rows, last - first), or
    None when a field is not a finite number (the caller then parses line by line, to name
    it). One conversion for all lines instead of one per line: a third of the load time of
    the Intel log."""
    try:
        values = np.array([words[first:last] for _, words in rows], dtype=float)
    except ValueError:
        return None
    return values if np.all(np.isfinite(values)) else None


def parse_log(path: Path) -> ParsedLog:
    """Every message of the log at ``path`` (module docstring)."""
    path = Path(path)
    parsed = ParsedLog(path=path)
    old_lasers: dict[int, list[tuple[int, list[str]]]] = {}  # by beam count
    odometry_rows: list[tuple[int, list[str]]] = []
    order: list[tuple[str, int, int]] = []  # laser lines in file order: (group, beams, index)
    robot_lasers: list[LaserMessage] = []
    for number, line in enumerate(log_text(path).splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        tag = words[0]
        if tag.startswith("#"):
            parsed.comments += 1
        elif tag in ("FLASER", "RLASER"):
            _need(path, number, tag, words, 2, "num_readings")
            beams = _count(path, number, tag, words[1], "num_readings")
            _need(
                path,
                number,
                tag,
                words,
                beams + 9,
                f"{beams} ranges, x y theta, odom_x odom_y odom_theta, ipc_timestamp",
            )
            group = old_lasers.setdefault(beams, [])
            order.append(("old", beams, len(group)))
            group.append((number, words))
        elif tag == "ROBOTLASER1":
            order.append(("robot", 0, len(robot_lasers)))
            robot_lasers.append(parse_robot_laser(path, number, words))
        elif tag == "ODOM":
            _need(path, number, "ODOM", words, 8, "x y theta tv rv accel ipc_timestamp")
            odometry_rows.append((number, words))
        elif tag == "PARAM":
            if len(words) < 3:
                raise InputError(f"{path}:{number}: PARAM needs a name and a value")
            parsed.parameters[words[1]] = Parameter(words[1], words[2], number)
        else:
            parsed.skipped[tag] += 1
    converted: dict[int, list[LaserMessage]] = {}
    for beams, rows in old_lasers.items():
        values = _bulk(path, rows, 2, 8 + beams)
        if values is None:  # name the bad field
            converted[beams] = [parse_old_laser(path, number, words) for number, words in rows]
            continue
        step = guessed_angle_step_rad(beams)
        converted[beams] = [
            LaserMessage(
                kind=words[0],
                line=number,
                stamp=_stamp(path, number, words[0], words[8 + beams]),
                ranges=row[:beams],
                start_angle_rad=float(-np.pi / 2.0),
                angle_step_rad=step,
                max_range_m=NO_RETURN_RANGE_M,
                odometry=row[beams + 3 : beams + 6],
                logged_pose=row[beams : beams + 3],
            )
            for (number, words), row in zip(rows, values)
        ]
    parsed.lasers = [
        converted[beams][index] if group == "old" else robot_lasers[index]
        for group, beams, index in order
    ]
    values = _bulk(path, odometry_rows, 1, 7) if odometry_rows else np.zeros((0, 6))
    if values is None:
        parsed.odometry = [parse_odometry(path, number, words) for number, words in odometry_rows]
    else:
        parsed.odometry = [
            OdometryMessage(
                line=number,
                stamp=_stamp(path, number, "ODOM", words[7]),
                pose=row[0:3],
                velocity=row[3:5],
            )
            for (number, words), row in zip(odometry_rows, values)
        ]
    if not parsed.lasers:
        raise InputError(
            f"{path}: no laser lines (FLASER, RLASER or ROBOTLASER1): not a CARMEN laser log?"
        )
    return parsed
