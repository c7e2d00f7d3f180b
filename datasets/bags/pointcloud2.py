"""Decoding ``sensor_msgs/PointCloud2`` messages (already deserialized by rosbags) with numpy.

Any field layout works: the message's own ``fields`` (name, offset, datatype, count) become
a numpy structured dtype over the raw bytes, of which only x, y, z and the per-point time
are read. Organized clouds (height > 1) and row padding (``row_step > width * point_step``)
are handled; non-finite points (organized clouds mark misses with NaN) are dropped and
counted.

Per-point time fields, first found of ``time``, ``t``, ``timestamp``, ``offset_time``:
- units: integer fields are nanoseconds (Ouster ``t``, Livox ``offset_time``); float fields
  are seconds (Velodyne ``time``), unless their spread within one cloud exceeds
  ``NANOSECOND_SPREAD_S`` (a sweep lasts well under a second), in which case they are
  nanoseconds. ``time_unit`` overrides the guess.
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
_NUMPY_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_UNIT_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


@dataclass(frozen=True)
class DecodedCloud:
    """Finite points of one cloud.

    Attributes:
        points: (n, 3) float64 [m], sensor frame.
        point_times: (n,) [s] relative to the header stamp, or None without a time field.
        nonfinite: how many points were dropped as NaN/inf.
        time_field: the name of the time field used, or None.
    """

    points: np.ndarray
    point_times: np.ndarray | None
    nonfinite: int
    time_field: str | None


def cloud_dtype(
    fields, point_step: int, bigendian: bool, names: tuple[str, ...], where: str
) -> np.dtype:
    """Structured dtype reading ``names`` out of records of ``point_step`` bytes."""
    by_name = {field.name: field for field in fields}
    order = ">" if bigendian else "<"
    formats, offsets = [], []
    for name in names:
        field = by_name[name]
        if field.datatype not in _NUMPY_TYPES:
            raise InputError(
                f"{where}: PointCloud2 field '{name}' has unknown datatype {field.datatype}"
            )
        size = np.dtype(_NUMPY_TYPES[field.datatype]).itemsize
        if field.offset + size > point_step:
            raise InputError(
                f"{where}: PointCloud2 field '{name}' (offset {field.offset}) runs past point_step {point_step}"
            )
        formats.append(order + _NUMPY_TYPES[field.datatype])
        offsets.append(field.offset)
    return np.dtype(
        {"names": list(names), "formats": formats, "offsets": offsets, "itemsize": point_step}
    )


def decode_pointcloud2(
    message, stamp_s: float, where: str, time_unit: str = "auto"
) -> DecodedCloud:
    """Finite xyz points and relative per-point times of a PointCloud2 message.

    Args:
        message: a rosbags ``sensor_msgs/msg/PointCloud2``.
        stamp_s: its header stamp [s] (to make absolute point times relative).
        where: ``file, topic, time`` for error messages.
        time_unit: ``auto``, ``s``, ``ms``, ``us`` or ``ns``.

    Raises:
        InputError: no x/y/z fields, a field beyond ``point_step``, data shorter than the
            declared size.
    """
    names = {field.name for field in message.fields}
    missing = [axis for axis in ("x", "y", "z") if axis not in names]
    if missing:
        present = ", ".join(sorted(names)) or "none"
        raise InputError(
            f"{where}: PointCloud2 has no {'/'.join(missing)} field (fields: {present})"
        )
    time_field = next((name for name in TIME_FIELDS if name in names), None)
    wanted = ("x", "y", "z") + ((time_field,) if time_field else ())
    dtype = cloud_dtype(
        message.fields, int(message.point_step), bool(message.is_bigendian), wanted, where
    )
    height, width, point_step, row_step = (
        int(message.height),
        int(message.width),
        int(message.point_step),
        int(message.row_step),
    )
    if height * width == 0:
        return DecodedCloud(np.zeros((0, 3)), np.zeros(0) if time_field else None, 0, time_field)
    row_bytes = width * point_step
    row_step = max(row_step, row_bytes)
    data = np.asarray(message.data, dtype=np.uint8)
    needed = row_step * (height - 1) + row_bytes
    if data.size < needed:
        raise InputError(
            f"{where}: PointCloud2 data has {data.size} bytes, its header declares {needed}"
        )
    if row_step == row_bytes:
        raw = data[: height * row_bytes]
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
    times = None
    if time_field:
        times = relative_point_seconds(records[time_field], stamp_s, time_unit)
        finite &= np.isfinite(times)
        times = times[finite]
    return DecodedCloud(
        points[finite], times, int(finite.size - np.count_nonzero(finite)), time_field
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
        spread = float(finite.max() - finite.min()) if finite.size else 0.0
        scale = 1e-9 if integer or spread > NANOSECOND_SPREAD_S else 1.0
    else:
        scale = _UNIT_SCALE[time_unit]
    seconds = values * scale
    finite = seconds[np.isfinite(seconds)]
    if finite.size and float(np.median(finite)) > ABSOLUTE_TIME_S:
        seconds = seconds - stamp_s
    return seconds
