"""Decoding ``sensor_msgs/PointCloud2`` messages (already deserialized by rosbags) with numpy.

Any field layout works: the message's own ``fields`` (name, offset, datatype, count) become
a numpy structured dtype over the raw bytes, of which only x, y, z and the per-point time
are read. Organized clouds (height > 1) and row padding (``row_step > width * point_step``)
are handled; non-finite points (organized clouds mark misses with NaN) are dropped and
counted.

Checked for meaning, not only form:
- x, y and z must be FLOAT32 or FLOAT64: anything else (a cloud declaring ``x`` as UINT8
  ran to a wrong trajectory with no corner found) is an ``InputError`` naming the field
  and its declared type.
- the layout must hold together: every field inside ``point_step``, ``row_step >= width *
  point_step`` and ``len(data) == row_step * height``; a message that breaks it raises
  ``MalformedCloud``, which the reader counts as a skipped message (one broken message is
  not a broken bag; many are, above ``max_skipped_fraction``).
- points no lidar gives are dropped and said in ``DecodedCloud.problems`` (the reader
  counts such clouds): a coordinate beyond ``MAX_POINT_RANGE_M``, a per-point time further
  from the stamp than ``max_time_s`` (by default ``ABSOLUTE_TIME_S``, longer than any sweep
  lasts; the bag reader passes one and a half of the topic's sweeps), non-finite points in
  a cloud that declares itself dense. A flipped word in a cloud's data gives such values.

Per-point time fields, first found of ``time``, ``t``, ``timestamp``, ``offset_time``:
- units: integer fields are nanoseconds (Ouster ``t``, Livox ``offset_time``); float fields
  are seconds (Velodyne ``time``), unless their spread within one cloud exceeds
  ``NANOSECOND_SPREAD_S`` (a sweep lasts well under a second), in which case they are
  nanoseconds. The spread is twice the interquartile range (a sweep's times spread evenly),
  so that one corrupted time cannot turn a cloud's seconds into nanoseconds. ``time_unit``
  overrides the guess.
- origin: times whose median exceeds ``ABSOLUTE_TIME_S`` (longer than any sweep lasts) are
  absolute (e.g. Hesai ``timestamp``) and are made relative to the header stamp. The result is always seconds relative to the
  cloud's stamp, i.e. ``PointCloud.point_times``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError

TIME_FIELDS = ("time", "t", "timestamp", "offset_time")
NANOSECOND_SPREAD_S = 10.0
ABSOLUTE_TIME_S = 1.0
MAX_POINT_RANGE_M = 1e4
"""No lidar measures 10 km (the longest-range ones reach about 1 km); a sensor-frame point
beyond it is a corrupted value, dropped and counted."""
_NUMPY_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_TYPE_NAMES = {
    1: "INT8",
    2: "UINT8",
    3: "INT16",
    4: "UINT16",
    5: "INT32",
    6: "UINT32",
    7: "FLOAT32",
    8: "FLOAT64",
}
COORDINATE_TYPES = (7, 8)  # FLOAT32, FLOAT64
_UNIT_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


class MalformedCloud(InputError):
    """A PointCloud2 whose layout contradicts itself (module docstring): one broken message,
    which the reader skips and counts. ``problem`` says what, without the where."""

    def __init__(self, where: str, problem: str) -> None:
        super().__init__(f"{where}: malformed PointCloud2: {problem}")
        self.problem = problem


@dataclass(frozen=True)
class DecodedCloud:
    """Finite points of one cloud.

    Attributes:
        points: (n, 3) float64 [m], sensor frame.
        point_times: (n,) [s] relative to the header stamp, or None without a time field.
        nonfinite: how many points were dropped as NaN/inf.
        time_field: the name of the time field used, or None.
        problems: what was implausible in the cloud and dropped (module docstring), one
            phrase each, e.g. ``3 non-finite points in a dense cloud``; empty for a sound
            cloud.
    """

    points: np.ndarray
    point_times: np.ndarray | None
    nonfinite: int
    time_field: str | None
    problems: tuple[str, ...] = ()


def _type_name(datatype: int) -> str:
    return f"{_TYPE_NAMES.get(datatype, 'unknown')} (datatype {datatype})"


def layout_problem(message) -> str | None:
    """What makes a PointCloud2's layout inconsistent (module docstring), or None."""
    point_step, row_step = int(message.point_step), int(message.row_step)
    height, width = int(message.height), int(message.width)
    for field in message.fields:
        if field.datatype not in _NUMPY_TYPES:
            return f"field '{field.name}' has {_type_name(field.datatype)}"
        size = np.dtype(_NUMPY_TYPES[field.datatype]).itemsize * max(int(field.count), 1)
        if field.offset + size > point_step:
            return (
                f"field '{field.name}' (offset {field.offset}, {size} bytes) runs past "
                f"point_step {point_step}"
            )
    if row_step < width * point_step:
        return f"row_step {row_step} is less than width {width} x point_step {point_step}"
    if len(message.data) != row_step * height:
        return (
            f"data has {len(message.data)} bytes, row_step {row_step} x height {height} "
            f"declares {row_step * height}"
        )
    return None


def cloud_dtype(fields, point_step: int, bigendian: bool, names: tuple[str, ...]) -> np.dtype:
    """Structured dtype reading ``names`` out of records of ``point_step`` bytes (of a
    message whose ``layout_problem`` is None)."""
    by_name = {field.name: field for field in fields}
    order = ">" if bigendian else "<"
    formats, offsets = [], []
    for name in names:
        field = by_name[name]
        formats.append(order + _NUMPY_TYPES[field.datatype])
        offsets.append(field.offset)
    return np.dtype(
        {"names": list(names), "formats": formats, "offsets": offsets, "itemsize": point_step}
    )


def decode_pointcloud2(
    message,
    stamp_s: float,
    where: str,
    time_unit: str = "auto",
    max_time_s: float = ABSOLUTE_TIME_S,
) -> DecodedCloud:
    """Plausible finite xyz points and relative per-point times of a PointCloud2 message.

    Args:
        message: a rosbags ``sensor_msgs/msg/PointCloud2``.
        stamp_s: its header stamp [s] (to make absolute point times relative).
        where: ``file, topic, time`` for error messages.
        time_unit: ``auto``, ``s``, ``ms``, ``us`` or ``ns``.
        max_time_s: points timed further from the stamp [s] are dropped (module docstring).

    Raises:
        InputError: no x/y/z fields, or coordinates that are not FLOAT32/FLOAT64.
        MalformedCloud: an inconsistent layout (``layout_problem``).
    """
    by_name = {field.name: field for field in message.fields}
    missing = [axis for axis in ("x", "y", "z") if axis not in by_name]
    if missing:
        present = ", ".join(sorted(by_name)) or "none"
        raise InputError(
            f"{where}: PointCloud2 has no {'/'.join(missing)} field (fields: {present})"
        )
    for axis in ("x", "y", "z"):
        if by_name[axis].datatype not in COORDINATE_TYPES:
            raise InputError(
                f"{where}: PointCloud2 field '{axis}' is {_type_name(by_name[axis].datatype)}; "
                "coordinates must be FLOAT32 or FLOAT64"
            )
    problem = layout_problem(message)
    if problem:
        raise MalformedCloud(where, problem)
    time_field = next((name for name in TIME_FIELDS if name in by_name), None)
    wanted = ("x", "y", "z") + ((time_field,) if time_field else ())
    dtype = cloud_dtype(message.fields, int(message.point_step), bool(message.is_bigendian), wanted)
    height, width, row_step = int(message.height), int(message.width), int(message.row_step)
    if height * width == 0:
        return DecodedCloud(np.zeros((0, 3)), np.zeros(0) if time_field else None, 0, time_field)
    row_bytes = width * int(message.point_step)
    data = np.asarray(message.data, dtype=np.uint8)
    if row_step == row_bytes:
        raw = data
    else:  # drop the padding at the end of every row
        raw = (
            np.lib.stride_tricks.as_strided(data, shape=(height, row_bytes), strides=(row_step, 1))
            .copy()
            .ravel()
        )
    records = np.frombuffer(
        raw.tobytes() if not raw.flags.c_contiguous else raw, dtype=dtype, count=height * width
    )
    points = np.column_stack([records["x"], records["y"], records["z"]]).astype(np.float64)
    finite = np.isfinite(points).all(axis=1)
    problems = []
    if message.is_dense and not finite.all():
        problems.append(f"{int(np.count_nonzero(~finite))} non-finite points in a dense cloud")
    with np.errstate(invalid="ignore"):
        implausible = finite & (np.abs(points).max(axis=1) > MAX_POINT_RANGE_M)
    times = None
    if time_field:
        times = relative_point_seconds(records[time_field], stamp_s, time_unit)
        finite &= np.isfinite(times)
        with np.errstate(invalid="ignore"):
            implausible |= finite & (np.abs(times) > max_time_s)
    if implausible.any():
        problems.append(
            f"{int(np.count_nonzero(implausible))} of {implausible.size} points beyond "
            f"{MAX_POINT_RANGE_M:g} m or timed more than {max_time_s:.3g} s from the stamp"
        )
    keep = finite & ~implausible
    return DecodedCloud(
        points[keep],
        None if times is None else times[keep],
        int(finite.size - np.count_nonzero(finite)),
        time_field,
        tuple(problems),
    )


def encode_pointcloud2(typestore, header, records: np.ndarray, is_dense: bool):
    """The inverse of ``decode_pointcloud2`` for writers (the synthetic bags, tests): a
    ``sensor_msgs/msg/PointCloud2`` of ``typestore`` whose points are ``records``.

    Args:
        typestore: a rosbags typestore (ROS 1 or ROS 2). header: its ``std_msgs/msg/Header``.
        records: a little-endian structured array, (n,) for an unorganized cloud (height 1)
            or (rows, columns) for an organized one; every field of its dtype becomes a
            ``PointField`` at its offset, and padding stays (point_step = itemsize).
        is_dense: the message's flag (False when some points are invalid, e.g. NaN misses).
    """
    datatypes = {code: datatype for datatype, code in _NUMPY_TYPES.items()}
    types = typestore.types
    fields = []
    for name in records.dtype.names:
        field_type, offset = records.dtype.fields[name][:2]
        if field_type.byteorder == ">" or field_type.str[1:] not in datatypes:
            raise ValueError(
                f"PointCloud2 field '{name}': no little-endian datatype for {field_type}"
            )
        fields.append(
            types["sensor_msgs/msg/PointField"](
                name=name, offset=offset, datatype=datatypes[field_type.str[1:]], count=1
            )
        )
    rows, columns = (1, records.shape[0]) if records.ndim == 1 else records.shape
    return types["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=rows,
        width=columns,
        fields=fields,
        is_bigendian=False,
        point_step=records.dtype.itemsize,
        row_step=records.dtype.itemsize * columns,
        data=np.frombuffer(np.ascontiguousarray(records).tobytes(), dtype=np.uint8),
        is_dense=is_dense,
    )


def relative_point_seconds(values: np.ndarray, stamp_s: float, time_unit: str) -> np.ndarray:
    """Per-point times as seconds relative to the header stamp (see the module docstring)."""
    integer = values.dtype.kind in "iu"
    values = values.astype(np.float64)
    if time_unit == "auto":
        finite = values[np.isfinite(values)]
        # twice the interquartile range: the length of an even sweep (module docstring)
        spread = 2.0 * float(np.subtract(*np.percentile(finite, [75, 25]))) if finite.size else 0.0
        scale = 1e-9 if integer or spread > NANOSECOND_SPREAD_S else 1.0
    else:
        scale = _UNIT_SCALE[time_unit]
    seconds = values * scale
    finite = seconds[np.isfinite(seconds)]
    if finite.size and float(np.median(finite)) > ABSOLUTE_TIME_S:
        seconds = seconds - stamp_s
    return seconds
