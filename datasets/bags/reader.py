"""Reading ROS 1 ``.bag`` files and ROS 2 bags (sqlite3 or mcap) lazily, in stamp order.

The entry point: ``read_stream``; every other name is imported from the module that owns
it:
- ``datasets.bags.bag_file``: opening a bag of any format through rosbags' ``AnyReader``
  and iterating its messages with their header stamps (integer nanoseconds -> float
  seconds, once, there);
- ``datasets.bags.topics``: which topics are read (``discover_topics``, ``BagTopics``);
- ``datasets.bags.message_types``: the message type names;
- ``datasets.bags.convert``: one message -> a measurement in the workbench vocabulary;
- ``datasets.bags.ground_truth``: a ground-truth topic read whole;
- ``datasets.bags.read_report``: ``ReadSettings``, ``ReadReport``, ``check_skips``;
- ``datasets.bags.time_base``: the common time base (``TimeBase``);
- ``datasets.bags.spans``: each topic's span, the first lidar pose, the sweep period.

Order: a bag is ordered by log time, but a driver logs a cloud when its sweep ends while its
stamp is the sweep start, so stamps are not ordered across topics. A small reorder buffer
(``reorder_window_s``) re-sorts by stamp; a message whose stamp is older than one already
emitted on its topic (stamps going backwards), or older than the buffer can repair, is
skipped and counted in the ``ReadReport`` (never silently reordered beyond the window).

Time base: sensors rarely start together (an IMU driver started before the lidar records
samples before the first sweep). ``topic_spans`` reads each topic's first and last stamp from
the two ends of the bag, ``common_time_base`` intersects them (``TimeBase``), and
``read_stream`` drops, and counts in the ``ReadReport``, every message stamped outside it.

Meaning, not only form: a corrupted bag (flipped words) mostly still decodes, into numbers
that look like any others. The checks that catch what a message can show, each violation
skipped (or, for clouds with a few implausible points, repaired by dropping them) and
counted per topic in the ``ReadReport``, printed as warnings naming the topic and count, and
an ``InputError`` when a topic's skipped and repaired messages exceed
``max_skipped_fraction`` (``check_skips``):
- a message that does not deserialize (``iter_messages``);
- a header stamp that jumps by more than ``STAMP_JUMP_S`` against the bag's record time,
  compared with its topic's first message (so a constant offset between the driver's clock
  and the recorder's is fine) (``datasets.bags.bag_file``);
- PointCloud2 layout, coordinate types, points (``datasets.bags.pointcloud2``);
- IMU samples: non-finite, or |gyro| above ``MAX_GYRO_RAD_S``, |accel| above
  ``MAX_ACCEL_M_S2`` (``datasets.bags.convert``);
- ground-truth poses: non-finite, an orientation that is not a unit quaternion (within
  ``UNIT_QUATERNION_TOLERANCE``), a position beyond ``MAX_POSITION_M`` or reached from the
  previous pose faster than ``MAX_TRUTH_SPEED_M_S`` (``datasets.bags.ground_truth``);
- GPS fixes: latitude or longitude out of range (``datasets.bags.convert``).
Containers check themselves where they can: rosbags verifies an MCAP chunk's CRC when the
writer stored one (``ros2 bag record`` does; rosbags' own writer stores none), and a
mismatch is an ``InputError``; sqlite3 and ROS 1 bags carry no checksums of messages.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages, open_bag
from datasets.bags.convert import (
    convert,
)
from datasets.bags.message_types import (
    POINTCLOUD2,
)
from datasets.bags.read_report import ReadReport, ReadSettings, check_skips
from datasets.errors import InputError
from datasets.measurements import Measurement


def read_stream(
    path: Path, topics: list[str], settings: ReadSettings, report: ReadReport, reader=None
) -> Iterator[tuple[str, Measurement]]:
    """``(topic, measurement)`` of the given topics, lazily, in stamp order (module docstring).
    ``reader``: the bag already open (``open_bag``), else it is opened here, once."""
    if reader is None:
        with open_bag(path) as opened:
            yield from read_stream(path, topics, settings, report, opened)
        return
    heap: list[tuple[float, int, str, Measurement]] = []
    counter = itertools.count()
    last_on_topic: dict[str, float] = {}
    emitted = -np.inf
    for topic, msgtype, stamp, message in iter_messages(reader, path, topics, report=report):
        if stamp <= last_on_topic.get(topic, -np.inf):
            report.skip(
                topic,
                "stamp went backwards (or repeated)",
                stamp,
                f"previous {last_on_topic[topic]:.9f}",
            )
            continue
        if stamp < emitted:
            report.skip(
                topic, "stamp older than the reorder window", stamp, f"already at {emitted:.9f}"
            )
            continue
        base = settings.time_base
        if base is not None and msgtype == POINTCLOUD2:
            outside = not base.keeps_cloud(stamp)
        else:
            outside = base is not None and not base.contains(stamp)
        if outside and msgtype == POINTCLOUD2:  # trimmed undecoded: decoding is the cost
            last_on_topic[topic] = stamp
            report.trim(topic, stamp, settings.time_base)
            continue
        # other messages are checked first, so a NaN IMU sample counts as a skip wherever
        measurement = convert(path, topic, msgtype, stamp, message, settings, report)
        last_on_topic[topic] = stamp
        if measurement is None:
            continue
        if outside:
            report.trim(topic, stamp, settings.time_base)
            continue
        heapq.heappush(heap, (stamp, next(counter), topic, measurement))
        while heap and heap[0][0] < stamp - settings.reorder_window_s:
            emitted, _, out_topic, out = heapq.heappop(heap)
            yield out_topic, out
    while heap:
        emitted, _, out_topic, out = heapq.heappop(heap)
        yield out_topic, out
    _check_counts(path, reader, topics, settings, report)
    check_skips(path, topics, settings.max_skipped_fraction, report)


def _check_counts(path: Path, reader, topics: list[str], settings: ReadSettings, report) -> None:
    """Messages read per topic against the bag's index, once the whole bag was read: fewer
    is a warning line in ``report``, and an ``InputError`` beyond
    ``settings.max_missing_fraction`` (the reader silently skips what a damaged chunk held:
    a mcap bag with 64 KiB zeroed read 78 of its 80 clouds)."""
    for topic in topics:
        connection = reader.topics.get(topic)
        indexed = int(connection.msgcount) if connection is not None else 0
        read = int(report.messages[topic])
        if read >= indexed:
            continue
        report.missing[topic] = (read, indexed)
        if indexed - read > settings.max_missing_fraction * indexed:
            raise InputError(
                f"{path}: read {read} of the {indexed} messages its index lists on {topic} "
                f"(damaged bag?); more than max_missing_fraction={settings.max_missing_fraction}"
                " (raise it to accept)"
            )
