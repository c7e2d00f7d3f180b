"""What a pass over a bag is told and what it found: ``ReadSettings`` (how to convert, the
time base to trim to, how many bad messages to accept) and ``ReadReport`` (what was skipped,
repaired, trimmed or read short of the index, per topic, and why).

Meaning, not only form: a corrupted bag (flipped words) mostly still decodes, into numbers
that look like any others. The checks that catch what a message can show
(``datasets.bags.reader`` lists them) skip each violation (or, for clouds with a few
implausible points, repair it by dropping them) and count it per topic in the
``ReadReport``, printed as warnings naming the topic and count; ``check_skips`` raises an
``InputError`` when a topic's skipped and repaired messages exceed ``max_skipped_fraction``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from datasets.bags.pointcloud2 import ABSOLUTE_TIME_S
from datasets.bags.time_base import TimeBase
from datasets.errors import InputError


@dataclass
class ReadReport:
    """What a pass over a bag skipped, and why (mutable: filled while reading).

    Attributes:
        skipped: count per ``(topic, reason)``.
        repaired: messages kept after dropping what was implausible in them (points of a
            cloud), count per ``(topic, reason)``; they count towards
            ``max_skipped_fraction`` as skips do.
        examples: the first skip or repair of each ``(topic, reason)`` as a message naming
            the time.
        nonfinite_points: NaN/inf points dropped from clouds.
        messages: messages read per topic.
        missing: topic -> (messages read, messages its index lists) where fewer were read
            (a damaged bag whose index promises more than its chunks hold).
        trimmed: ``(topic, "before" | "after")`` -> [count, first stamp, last stamp, the
            ``TimeBase`` bound's description]: messages outside the common time base
            (not skips: they do not count towards ``max_skipped_fraction``).
    """

    skipped: Counter = field(default_factory=Counter)
    repaired: Counter = field(default_factory=Counter)
    examples: dict[tuple[str, str], str] = field(default_factory=dict)
    nonfinite_points: int = 0
    messages: Counter = field(default_factory=Counter)
    missing: dict[str, tuple[int, int]] = field(default_factory=dict)
    trimmed: dict[tuple[str, str], list] = field(default_factory=dict)

    def skip(self, topic: str, reason: str, stamp_s: float, detail: str = "") -> None:
        self._count(self.skipped, topic, reason, stamp_s, detail)

    def repair(self, topic: str, reason: str, stamp_s: float, detail: str = "") -> None:
        """Count a message kept after dropping its implausible parts."""
        self._count(self.repaired, topic, reason, stamp_s, detail)

    def _count(
        self, counter: Counter, topic: str, reason: str, stamp_s: float, detail: str
    ) -> None:
        key = (topic, reason)
        counter[key] += 1
        self.examples.setdefault(
            key, f"{topic} at t={stamp_s:.9f}: {reason}{(' (' + detail + ')') if detail else ''}"
        )

    def bad_messages(self, topic: str) -> tuple[int, int]:
        """(skipped, repaired) messages of ``topic``."""

        def of_topic(counter: Counter) -> int:
            return sum(count for (name, _), count in counter.items() if name == topic)

        return of_topic(self.skipped), of_topic(self.repaired)

    def trim(self, topic: str, stamp_s: float, time_base: TimeBase) -> None:
        """Count a message stamped outside ``time_base`` (before its start or after its end)."""
        side = "before" if stamp_s < time_base.start_s else "after"
        entry = self.trimmed.get((topic, side))
        if entry is None:
            bound = (
                f"the start of the common time base t={time_base.start_s:.9f} ({time_base.start_by})"
                if side == "before"
                else f"the end of the common time base t={time_base.end_s:.9f} ({time_base.end_by})"
            )
            self.trimmed[(topic, side)] = [1, stamp_s, stamp_s, bound]
        else:
            entry[0] += 1
            entry[1], entry[2] = min(entry[1], stamp_s), max(entry[2], stamp_s)

    def lines(self) -> list[str]:
        """One line per skip kind: ``N x topic: reason (first at t=...)``, then the
        messages trimmed to the common time base, then topics read short of their index."""
        lines = [
            f"skipped {count} x {self.examples[key]}" for key, count in sorted(self.skipped.items())
        ]
        lines += [
            f"repaired {count} x {self.examples[key]}"
            for key, count in sorted(self.repaired.items())
        ]
        lines += [
            f"trimmed {count} x {topic} at t={first:.9f}..{last:.9f}: {side} {bound}"
            for (topic, side), (count, first, last, bound) in sorted(self.trimmed.items())
        ]
        lines += [
            f"read {read} of the {indexed} messages its index lists on {topic}"
            for topic, (read, indexed) in sorted(self.missing.items())
        ]
        return lines


@dataclass(frozen=True)
class ReadSettings:
    """How to convert: point time unit, GPS origin and default GPS sigma, reorder window,
    the lidar-to-body extrinsic (``p_body = R p_lidar + t``), if any, and the common time
    base to trim to, if any."""

    time_unit: str = "auto"
    max_point_time_s: float = ABSOLUTE_TIME_S  # points timed further from the stamp dropped
    # point_times=azimuth: the sweep [s] over which clouds without times are timed by azimuth
    azimuth_sweep_s: float | None = None
    lidar_to_body: np.ndarray | None = None  # (4, 4) extrinsic applied to every cloud
    gps_origin: tuple[float, float, float] | None = None
    gps_sigma_m: float = 1.0
    reorder_window_s: float = 1.0
    max_missing_fraction: float = 0.01
    max_skipped_fraction: float = 0.05
    time_base: TimeBase | None = None  # messages stamped outside it are trimmed and counted
    laser_mounting: np.ndarray | None = None  # (3,) 2-D laser in the body frame: x, y, theta


def check_skips(path: Path, topics: list[str], max_fraction: float, report: ReadReport) -> None:
    """``InputError`` when more than ``max_fraction`` of a topic's messages were skipped or
    repaired (NaN IMU samples, non-finite poses, empty clouds, implausible values, ...): a
    few are counted warnings, most of a topic is a broken recording, not a quirk."""
    for topic in topics:
        skipped, repaired = report.bad_messages(topic)
        read = int(report.messages[topic])
        if skipped + repaired > max_fraction * read:
            what = " or ".join(
                word for word, count in (("skipped", skipped), ("repaired", repaired)) if count
            )
            keys = sorted(key for key in {*report.skipped, *report.repaired} if key[0] == topic)
            raise InputError(
                f"{path}: {skipped + repaired} of the {read} messages on {topic} {what} "
                f"(first: {report.examples[keys[0]]}); "
                f"more than max_skipped_fraction={max_fraction} (raise it to accept)"
            )
