"""Opening a bag of any format and iterating its messages: ROS 1 ``.bag`` files and ROS 2
bags (sqlite3 or mcap).

Everything goes through ``rosbags.highlevel.AnyReader`` and its type store and deserializer
(the bag's embedded definitions; ROS 1 Noetic / ROS 2 Humble definitions when a bag has
none). ``iter_messages`` yields the messages in log order with their header stamps (integer
nanoseconds -> float seconds, once, here: ``stamp_seconds``).

Checks of form, each message skipped and counted in the ``ReadReport`` when one is given
(``datasets.bags.read_report``):
- a message that does not deserialize;
- a header stamp that jumps by more than ``STAMP_JUMP_S`` against the bag's record time,
  compared with its topic's first message (so a constant offset between the driver's clock
  and the recorder's is fine).
Containers check themselves where they can: rosbags verifies an MCAP chunk's CRC when the
writer stored one (``ros2 bag record`` does; rosbags' own writer stores none), and a
mismatch is an ``InputError``; sqlite3 and ROS 1 bags carry no checksums of messages.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from datasets.bags.read_report import ReadReport
from datasets.errors import InputError
from datasets.text_files import check_regular_file

STAMP_JUMP_S = 10.0
"""How far [s] a header stamp may move against the record (log) time from where its
topic's first message sits: drivers stamp at capture and the recorder logs on receipt, a
fraction of a second later (a sweep later for a cloud); a jump of ten seconds is a corrupted
stamp or one from another clock."""


def _default_typestore(path: Path):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE)


@contextmanager
def open_bag(path: str | Path):
    """An open ``AnyReader``; ``InputError`` naming the file for anything unreadable."""
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such bag file or folder")
    if not path.is_dir():
        check_regular_file(path, "bag file")  # a FIFO given as a bag would block the reader
    elif not (path / "metadata.yaml").is_file():
        raise InputError(f"{path}: a ROS 2 bag folder needs its metadata.yaml, found none")
    try:
        reader = AnyReader([path], default_typestore=_default_typestore(path))
        reader.open()
    except InputError:
        raise
    except Exception as error:  # rosbags raises several types for malformed or truncated bags
        # rosbags' YAML errors span several lines: the first says what is wrong
        first = str(error).strip().splitlines()[0] if str(error).strip() else ""
        raise InputError(f"{path}: cannot open bag ({type(error).__name__}: {first})") from None
    try:
        yield reader
    finally:
        try:
            reader.close()
        except Exception:  # closing a reader of a broken file must not hide the real error
            pass


def stamp_seconds(message, log_ns: int) -> float:
    """Header stamp [s] (the log time when the message has no header or a zero stamp)."""
    header = getattr(message, "header", None)
    if header is None:
        return log_ns * 1e-9
    stamp = header.stamp
    ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    return ns * 1e-9 if ns > 0 else log_ns * 1e-9


def iter_messages(
    reader,
    path: Path,
    topics: list[str],
    start_ns: int | None = None,
    stop_ns: int | None = None,
    wanted: Callable[[str], bool] | None = None,
    report: ReadReport | None = None,
) -> Iterator[tuple[str, str, float, object]]:
    """``(topic, type, stamp [s], message)`` in log order, of log times in
    ``[start_ns, stop_ns)`` when given, and only of topics ``wanted(topic)`` accepts at the
    time (the others are passed over undecoded); rosbags failures -> ``InputError`` naming
    the file, the topic and the time of the last good message.

    With a ``report``, every message read is counted in ``report.messages``, and a message
    that does not deserialize, or whose stamp jumps by more than ``STAMP_JUMP_S`` against
    the record time (module docstring), is skipped and counted there instead of yielded;
    without one, the first is an ``InputError`` and the second is yielded."""
    clock_offsets: dict[str, float] = {}  # stamp - record time of each topic's first message
    connections = [connection for connection in reader.connections if connection.topic in topics]
    if not connections:
        return
    stream = reader.messages(connections=connections, start=start_ns, stop=stop_ns)
    last = "the start"
    while True:
        try:
            item = next(stream)
        except StopIteration:
            return
        except Exception as error:
            raise InputError(
                f"{path}: unreadable after {last} ({type(error).__name__}: {error})"
            ) from None
        connection, log_ns, raw = item
        topic = connection.topic
        if wanted is not None and not wanted(topic):
            continue
        if report is not None:
            report.messages[topic] += 1
        try:
            message = reader.deserialize(raw, connection.msgtype)
        except Exception as error:
            if report is None:
                raise InputError(
                    f"{path}: {topic} at log time {log_ns * 1e-9:.9f}: cannot deserialize {connection.msgtype} ({type(error).__name__}: {error})"
                ) from None
            detail = f"{type(error).__name__}: {error}"
            report.skip(topic, "cannot deserialize the message", log_ns * 1e-9, detail)
            continue
        stamp = stamp_seconds(message, log_ns)
        if report is not None:
            offset = stamp - log_ns * 1e-9
            jump = offset - clock_offsets.setdefault(topic, offset)
            if abs(jump) > STAMP_JUMP_S:
                report.skip(
                    topic,
                    f"header stamp more than {STAMP_JUMP_S:g} s off the record time",
                    log_ns * 1e-9,
                    f"stamp {stamp:.9f}, {jump:+.3g} s against the topic's first message",
                )
                continue
        last = f"{topic} at t={stamp:.9f}"
        yield topic, connection.msgtype, stamp, message
