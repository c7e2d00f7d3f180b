"""``sensor_msgs/LaserScan`` -> ``datasets.laser2d.scan.PlanarScan``.

Each scan is read with its own geometry, never a topic-wide one: ``angle_min`` and
``angle_increment`` give beam ``i`` the angle ``angle_min + i * angle_increment`` (the
message's definition; ``angle_max`` is only checked against it, per topic, in
``describe_laserscan``), ``range_min`` / ``range_max`` are the scan's limits, and
``time_increment > 0`` gives beam ``i`` the time ``i * time_increment`` after the header
stamp (the message defines the stamp as the first beam's acquisition time). A scan with
``angle_increment < 0`` (a sensor sweeping clockwise) is stored reversed, so that angles
increase as ``PlanarScan`` expects, each beam keeping its range and time.

What a scan cannot mean is ``MalformedScan`` (the stream skips and counts it, as it does a
malformed cloud): fewer than two beams, a non-finite or zero ``angle_increment``, beams
spanning more than a turn, non-finite or inverted range limits. A ``time_increment`` that is
not finite, negative, or spreads the beams over more than ``MAX_SCAN_S`` is dropped (the
scan is kept without beam times) and counted as a repair. Readings outside the limits and
non-finite ranges (REP-117: +inf no return, NaN invalid) are kept as they are: they are the
beams without a return (``PlanarScan.returns``).
"""

from __future__ import annotations

import numpy as np

from datasets.laser2d.scan import PlanarScan

MAX_SCAN_S = 2.0
"""The longest span [s] the beams of one scan may be timed over: 2-D lasers sweep at 5 to
75 Hz; a longer span is a corrupted ``time_increment``."""


class MalformedScan(ValueError):
    """A LaserScan whose geometry cannot be read (``problem`` says which field and why)."""

    def __init__(self, problem: str) -> None:
        super().__init__(problem)
        self.problem = problem


def decode_laserscan(
    message, stamp: float, mounting: np.ndarray | None = None
) -> tuple[PlanarScan, str | None]:
    """The scan (module docstring) and, where its ``time_increment`` was dropped, why (else
    None). ``mounting``: the laser's pose in the body frame (x [m], y [m], theta [rad]),
    zero when None. ``MalformedScan`` for a scan that cannot be read."""
    ranges = np.asarray(message.ranges, dtype=float).ravel()
    n = ranges.size
    if n < 2:
        raise MalformedScan(f"ranges has {n} beam(s), fewer than 2")
    angle_min, increment = float(message.angle_min), float(message.angle_increment)
    if not (np.isfinite(angle_min) and np.isfinite(increment)) or increment == 0.0:
        raise MalformedScan(
            f"angle_min {angle_min:.6g}, angle_increment {increment:.6g}: "
            "need finite values and a non-zero increment"
        )
    if abs(increment) * (n - 1) > 2.0 * np.pi + abs(increment):
        raise MalformedScan(
            f"{n} beams of angle_increment {increment:.6g} rad span "
            f"{np.rad2deg(abs(increment) * (n - 1)):.1f} deg, more than a turn"
        )
    range_min, range_max = float(message.range_min), float(message.range_max)
    if not (np.isfinite(range_min) and np.isfinite(range_max)) or not 0.0 <= range_min < range_max:
        raise MalformedScan(
            f"range_min {range_min:.6g} m, range_max {range_max:.6g} m: "
            "need finite limits with 0 <= range_min < range_max"
        )
    angles = angle_min + increment * np.arange(n)
    time_increment = float(message.time_increment)
    beam_times, dropped = None, None
    if np.isfinite(time_increment) and time_increment > 0.0:
        if time_increment * (n - 1) <= MAX_SCAN_S:
            beam_times = time_increment * np.arange(n)
        else:
            dropped = (
                f"time_increment {time_increment:.6g} s spreads {n} beams over "
                f"{time_increment * (n - 1):.3g} s, more than {MAX_SCAN_S:g} s"
            )
    elif not np.isfinite(time_increment) or time_increment < 0.0:
        dropped = f"time_increment {time_increment:.6g} s (not a time between beams)"
    if increment < 0.0:  # a clockwise sweep: stored in increasing angle
        angles, ranges = angles[::-1].copy(), ranges[::-1].copy()
        beam_times = None if beam_times is None else beam_times[::-1].copy()
    scan = PlanarScan(
        t=stamp,
        ranges=ranges,
        angles=angles,
        min_range_m=range_min,
        max_range_m=range_max,
        mounting=np.zeros(3) if mounting is None else np.asarray(mounting, dtype=float),
        beam_times=beam_times,
    )
    return scan, dropped


def describe_laserscan(topic: str, message) -> str:
    """One line of what the first scan of ``topic`` says (the decision's evidence): beams,
    field of view, range limits, beam timing and whether ``angle_max`` agrees with
    ``angle_min + (n - 1) angle_increment``."""
    n = len(message.ranges)
    angle_min, increment = float(message.angle_min), float(message.angle_increment)
    last = angle_min + increment * (n - 1)
    off = abs(last - float(message.angle_max)) / abs(increment) if increment else np.inf
    agreement = (
        "angle_max agrees"
        if off <= 1.01
        else f"angle_max {np.rad2deg(float(message.angle_max)):.2f} deg is {off:.1f} increments "
        f"from the last beam's {np.rad2deg(last):.2f} deg (the beams are placed by angle_min "
        "and angle_increment)"
    )
    time_increment = float(message.time_increment)
    timing = (
        f"time_increment {1e6 * time_increment:.4g} us: per-beam times"
        if np.isfinite(time_increment) and time_increment > 0
        else "time_increment 0: the scan is taken at its stamp"
    )
    return (
        f"2-D laser {topic}: {n} beams from {np.rad2deg(angle_min):.2f} deg by "
        f"{np.rad2deg(increment):.4g} deg ({agreement}), ranges "
        f"{float(message.range_min):g}..{float(message.range_max):g} m, {timing} "
        f"(frame '{message.header.frame_id}')"
    )
