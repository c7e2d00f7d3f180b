"""The lidar front end in a sequence's stream (``with_front_end``): every cloud through the
front end, its odometry and corner scan interleaved with the other measurements in stamp
order, a cloud the IMU deskews held until the IMU has passed its sweep end.
"""

from __future__ import annotations

import numpy as np

from datasets.lidar.frontend import LidarFrontEnd
from datasets.measurements import ImuSample, PointCloud


def with_front_end(
    measurements,
    front_end: LidarFrontEnd,
    emit_clouds: bool = True,
    max_frames: int | None = None,
    emit_from_s: float | None = None,
):
    """Interleave the front end's odometry and corner scans into a stamp-ordered stream.

    Clouds stamped before ``emit_from_s`` (the sequence's start, when its first sweep began
    before it) go through the front end but are not emitted themselves.

    A frame's outputs are stamped at or after its cloud's stamp (``output_time``), and every
    later input is stamped at or after that too, so anything queued up to the current
    input's stamp can be released: the output stays time-ordered without a look-ahead
    window. A cloud the IMU deskews (``waits_for_imu``) is held until an IMU sample at or
    after its sweep end has arrived (or the next cloud, or the stream's end: the front end
    then falls back to KISS-ICP's deskew and counts it), and meanwhile only what is stamped
    before its outputs is released. The holding depends on the stream alone, not on the
    front end's cache, so every pass over a sequence gives the same order. Empty corner
    scans are not emitted. Stops before the ``max_frames + 1``-th cloud when ``max_frames``
    is set.
    """
    import heapq
    import itertools

    queue: list = []
    order = itertools.count()
    index = 0
    held: PointCloud | None = None  # a cloud waiting for the IMU to pass its sweep end
    held_until = np.inf  # its outputs' stamp
    latest_imu = -np.inf  # stamp of the latest IMU sample of this pass

    def run(cloud: PointCloud) -> None:
        nonlocal index
        frame = front_end.frame(index, cloud)
        index += 1
        if frame.odometry is not None:
            heapq.heappush(queue, (frame.t, next(order), frame.odometry))
        if frame.corners is not None and len(frame.corners.points):
            heapq.heappush(queue, (frame.t, next(order), frame.corners.scan(frame.t)))

    for measurement in measurements:
        if isinstance(measurement, PointCloud):
            if max_frames is not None and index + (held is not None) >= max_frames:
                break
            if held is not None:
                run(held)
                held, held_until = None, np.inf
            if emit_clouds and (emit_from_s is None or measurement.t >= emit_from_s):
                heapq.heappush(queue, (measurement.t, next(order), measurement))
            if front_end.waits_for_imu(measurement):
                held, held_until = measurement, front_end.output_time(measurement)
            else:
                run(measurement)
        else:
            heapq.heappush(queue, (measurement.t, next(order), measurement))
            if isinstance(measurement, ImuSample):
                front_end.add_imu(measurement)
                latest_imu = max(latest_imu, measurement.t)
        if held is not None and latest_imu >= held_until:
            run(held)
            held, held_until = None, np.inf
        while queue and queue[0][0] <= measurement.t and queue[0][0] < held_until:
            yield heapq.heappop(queue)[2]
    if held is not None:
        run(held)
    while queue:
        yield heapq.heappop(queue)[2]
