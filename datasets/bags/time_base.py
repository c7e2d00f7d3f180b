"""The common time base of a bag's streams (``TimeBase``): the interval they all cover.

Sensors rarely start together (an IMU driver started before the lidar records samples before
the first sweep). ``datasets.bags.spans.topic_spans`` reads each topic's first and last stamp
from the two ends of the bag, ``common_time_base`` intersects them (``TimeBase``), and
``read_stream`` (``datasets.bags.reader``) drops, and counts in the ``ReadReport``, every
message stamped outside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from datasets.errors import InputError


@dataclass(frozen=True)
class TimeBase:
    """The common interval of the streams a bag source uses: every message stamped before
    ``start_s`` or after ``end_s`` [s] is dropped and counted (``ReadReport.trimmed``).

    Attributes:
        start_s: the latest first stamp of the defining streams.
        end_s: the earliest last stamp of the defining streams.
        start_by: which stream sets the start (for messages), e.g. ``first stamp on /points``.
        end_by: which stream sets the end.
        spans: ``{stream: (first, last)}`` [s] of every defining stream.
        first_cloud_s: when the start is the front end's first pose
            (``start_at_first_pose``), the stamp of that pose's cloud (its sweep's start):
            clouds are kept from it, the other messages from ``start_s``; None otherwise.
    """

    start_s: float
    end_s: float
    start_by: str
    end_by: str
    spans: dict[str, tuple[float, float]]
    first_cloud_s: float | None = None

    def contains(self, stamp_s: float) -> bool:
        return self.start_s <= stamp_s <= self.end_s

    def keeps_cloud(self, stamp_s: float) -> bool:
        """Whether a cloud stamped ``stamp_s`` (its sweep start) is inside."""
        start = self.start_s if self.first_cloud_s is None else self.first_cloud_s
        return start <= stamp_s <= self.end_s

    def as_dict(self) -> dict:
        """JSON-ready, for a sequence's metadata."""
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "start_by": self.start_by,
            "end_by": self.end_by,
            "spans": {name: list(span) for name, span in self.spans.items()},
            "first_cloud_s": self.first_cloud_s,
        }


def common_time_base(path: Path, spans: dict[str, tuple[float, float]]) -> TimeBase | None:
    """``[max of the first stamps, min of the last stamps]`` of ``spans`` (None when empty);
    ``InputError`` naming every span when they do not overlap."""
    if not spans:
        return None
    start_topic = max(spans, key=lambda name: spans[name][0])
    end_topic = min(spans, key=lambda name: spans[name][1])
    start, end = spans[start_topic][0], spans[end_topic][1]
    if start > end:
        listed = "; ".join(f"{name} t={a:.3f}..{b:.3f}" for name, (a, b) in spans.items())
        raise InputError(
            f"{path}: the streams do not overlap in time ({listed}): "
            f"{start_topic} starts after {end_topic} ends"
        )
    return TimeBase(
        start_s=start,
        end_s=end,
        start_by=f"first stamp on {start_topic}",
        end_by=f"last stamp on {end_topic}",
        spans=dict(spans),
    )
