"""Time stamps of a CARMEN log: duplicated lines, lines out of order, and their repair.

Old logs are not in time order. On the shared Intel log, 631 scan lines and 602 odometry
lines have an ``ipc_timestamp`` before the previous line of their type, by up to 0.9 s,
while the poses in those lines follow the file order smoothly (sorting the odometry by its
stamps lengthens its path from 509 m to 675 m with steps of up to 0.92 m; in file order no
step exceeds 5 cm). The stamps themselves are wrong, and in one way: a time whose
microseconds are below 100000 was written without the leading zero of its fraction
(``%ld.%ld``) and later padded with trailing zeros to six decimals, so ``556.099081`` reads
``556.990810``. Its signature: the stamp ends in zeros, and with those zeros moved to the
front of the fraction it falls between its neighbours (``976053555.549906``,
``976053556.990810``, ``976053556.100282`` on the Intel log).

The repair keeps the file order, which the data vouch for, and changes the fewest stamps:
every stamp may be read as written or, when its fraction ends in ``k`` zeros, with ``1..k``
of them moved to the front; a dynamic program over each message type (scans, odometry)
picks the readings that make the stamps strictly increase at the least cost, a re-read
stamp costing 1 and a dropped line ``DROP_COST`` (``repair_order``). A line that no reading fits is dropped.
Every re-read and dropped line is counted and named in one printed line with examples.

Duplicated lines (a stamp equal to the previous line's of the same type) are dropped, the
first kept; the count says how many of them also repeated the content.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

LOOKBACK = 8
"""Lines a kept line may follow across dropped ones (the dynamic program's window)."""

DROP_COST = 1000.0
"""Cost of dropping a line, against 1 for re-reading a stamp: dropping is the last resort.
Re-reading is no exceptional event: every stamp whose fraction is below 0.1 is written that
way, a tenth of all lines. The repair agrees: on the Intel log it re-reads 1060 of 13631
scan stamps and 2093 of 26915 odometry stamps (7.8 % of each: the tenth, less those whose
next line does not show it) and drops one scan line. A cost of 4 would instead drop 14 scan
and 105 odometry lines and re-read only 5.4 % of the odometry's, which the mechanism does
not explain."""


def stamp_readings(stamp: str) -> list[float]:
    """The times [s] a written stamp may stand for: as written, then with 1..k of the k
    trailing zeros of its fraction moved to the front (the unpadded-microseconds reading,
    module docstring)."""
    whole, _, fraction = stamp.partition(".")
    readings = [float(stamp)]
    zeros = len(fraction) - len(fraction.rstrip("0"))
    for moved in range(1, zeros + 1):
        digits = fraction[: len(fraction) - moved]
        readings.append(int(whole) + (int(digits) if digits else 0) / 10 ** len(fraction))
    return readings


@dataclass(frozen=True)
class StampRepair:
    """What ``repair_order`` did to one message type.

    Attributes:
        kept: indices of the lines kept, in file order, (m,).
        times: their times [s], strictly increasing, (m,).
        reread: indices of the kept lines whose stamp was re-read, (r,).
        dropped: indices of lines dropped because no reading of their stamp fits, (q,).
        duplicates: indices of lines dropped as duplicates of the previous one, (u,).
        identical_duplicates: how many duplicates repeated the previous line's content too.
        backwards: lines whose stamp as written is not after the previous line's.
        largest_step_back_s: the largest step back in time as written [s].
    """

    kept: np.ndarray
    times: np.ndarray
    reread: np.ndarray
    dropped: np.ndarray
    duplicates: np.ndarray
    identical_duplicates: int
    backwards: int
    largest_step_back_s: float

    @property
    def changed(self) -> bool:
        """Whether anything was re-read or dropped."""
        return bool(len(self.reread) or len(self.dropped) or len(self.duplicates))


@njit(cache=True)
def _cheapest_order_kernel(
    readings: np.ndarray, counts: np.ndarray, lookback: int, drop_cost: float
) -> tuple[np.ndarray, np.ndarray]:
    """The dynamic program of ``repair_order`` over ``readings`` (n, R) (row ``i``'s first
    ``counts[i]`` entries; entry 0 as written): the kept rows and the reading chosen for each.
    Compiled (numba, cached like ``datasets.lidar.corner_kernels``): in Python the program
    took a second on the Intel log's 27 000 odometry lines."""
    count, width = readings.shape
    costs = np.full((count, width), np.inf)
    back_row = np.full((count, width), -1, dtype=np.int64)
    back_reading = np.full((count, width), -1, dtype=np.int64)
    for i in range(count):
        for j in range(counts[i]):
            value = readings[i, j]
            own = 0.0 if j == 0 else 1.0
            best = drop_cost * i + own  # every line before it dropped
            link_row, link_reading = -1, -1
            for earlier in range(max(0, i - lookback), i):
                skipped = drop_cost * (i - earlier - 1) + own
                for k in range(counts[earlier]):
                    if readings[earlier, k] < value and costs[earlier, k] + skipped < best:
                        best = costs[earlier, k] + skipped
                        link_row, link_reading = earlier, k
            costs[i, j] = best
            back_row[i, j], back_reading[i, j] = link_row, link_reading
    best, row, reading = np.inf, -1, -1
    for i in range(max(0, count - lookback), count):
        for j in range(counts[i]):
            total = costs[i, j] + drop_cost * (count - 1 - i)
            if total < best:
                best, row, reading = total, i, j
    kept = np.empty(count, dtype=np.int64)
    chosen = np.empty(count, dtype=np.int64)
    size = 0
    while row >= 0:
        kept[size], chosen[size] = row, reading
        size += 1
        row, reading = back_row[row, reading], back_reading[row, reading]
    return kept[:size][::-1].copy(), chosen[:size][::-1].copy()


def repair_order(stamps: list[str], contents: list[object] | None = None) -> StampRepair:
    """Duplicates dropped and the order repaired (module docstring) for one message type.

    Args:
        stamps: the ``ipc_timestamp`` of every line as written, in file order.
        contents: something comparable per line (the fields without the stamps), to say
            whether a duplicate stamp repeated the content; None: not said.
    """
    written = np.array([float(stamp) for stamp in stamps])
    steps = np.diff(written)
    backwards = int(np.count_nonzero(steps < 0))
    largest_back = float(-steps.min()) if backwards else 0.0
    duplicate = np.concatenate([[False], steps == 0])
    duplicates = np.flatnonzero(duplicate)
    identical = (
        sum(1 for i in duplicates if contents[i] == contents[i - 1]) if contents is not None else 0
    )
    candidates = np.flatnonzero(~duplicate)
    if np.all(np.diff(written[candidates]) > 0):
        return StampRepair(
            candidates,
            written[candidates],
            np.zeros(0, int),
            np.zeros(0, int),
            duplicates,
            identical,
            backwards,
            largest_back,
        )
    readings = [stamp_readings(stamps[i]) for i in candidates]
    counts = np.array([len(options) for options in readings], dtype=np.int64)
    table = np.full((len(readings), int(counts.max())), np.nan)
    for row, options in enumerate(readings):
        table[row, : len(options)] = options
    kept_positions, chosen = _cheapest_order_kernel(table, counts, LOOKBACK, DROP_COST)
    kept = candidates[kept_positions]
    times = table[kept_positions, chosen]
    reread = kept[chosen > 0]
    dropped = np.setdiff1d(candidates, kept)
    return StampRepair(kept, times, reread, dropped, duplicates, identical, backwards, largest_back)


def repair_line(what: str, repair: StampRepair, lines: np.ndarray, stamps: list[str]) -> str:
    """One printable line: what was re-read, dropped and deduplicated, with the evidence
    (an example line, its stamp as written and as read, its neighbours' times).

    Args:
        what: the message type (``FLASER scans``).
        lines: the 1-based file line of every message of the type.
        stamps: the stamps as written.
    """
    total = len(stamps)
    parts = [
        f"{what}: {repair.backwards} of {total} stamps go back in time as written (by up to "
        f"{repair.largest_step_back_s:.3f} s)"
    ]
    if len(repair.reread):
        index = int(repair.reread[0])
        position = int(np.searchsorted(repair.kept, index))
        before = repair.times[position - 1] if position > 0 else float("nan")
        after = repair.times[position + 1] if position + 1 < len(repair.times) else float("nan")
        parts.append(
            f"{len(repair.reread)} stamps re-read as unpadded microseconds, the file order kept "
            f"(e.g. line {lines[index]}: '{stamps[index]}' read as {repair.times[position]:.6f}, "
            f"between {before:.6f} and {after:.6f})"
        )
    if len(repair.dropped):
        shown = ", ".join(str(lines[i]) for i in repair.dropped[:5])
        parts.append(
            f"{len(repair.dropped)} dropped: no reading of their stamp fits their place "
            f"(line {shown}{' ...' if len(repair.dropped) > 5 else ''})"
        )
    if len(repair.duplicates):
        parts.append(
            f"{len(repair.duplicates)} dropped as duplicates of the previous line's stamp "
            f"({repair.identical_duplicates} with identical content; first at line "
            f"{lines[repair.duplicates[0]]})"
        )
    return "; ".join(parts)
