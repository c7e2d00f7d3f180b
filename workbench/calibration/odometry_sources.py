"""What ``workbench calibrate-noise`` fits against: a sequence's planar odometry as
increments, and a reference trajectory (its truth, or a smoother's estimate)."""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError
from datasets.measurements import Odometry
from datasets.odometry_calibration import Increments
from datasets.sequence import Sequence
from datasets.trajectory import Trajectory


def planar_increments(sequence: Sequence) -> Increments:
    """The sequence's odometry as planar increments ``(dx, dy, dtheta)``.

    Relative-pose odometry is taken as it is (its ``dt``); a velocity sample ``(v, omega)``
    at ``t`` covers the interval since the previous odometry sample (the workbench's
    convention), giving ``(v dt, 0, omega dt)``.
    """
    if sequence.dimension != 2:
        raise InputError(f"{sequence.name}: calibrate-noise fits planar odometry (2-D datasets)")
    ends: list[float] = []
    durations: list[float] = []
    values: list[np.ndarray] = []
    previous_t: float | None = None
    for measurement in sequence.measurements():
        if not isinstance(measurement, Odometry):
            continue
        if measurement.relative_pose is not None:
            dt = (
                measurement.dt
                if measurement.dt is not None
                else (measurement.t - previous_t if previous_t is not None else None)
            )
            if dt is not None and dt > 0:
                ends.append(measurement.t)
                durations.append(float(dt))
                values.append(np.asarray(measurement.relative_pose, float)[:3])
        elif measurement.velocity is not None and previous_t is not None:
            dt = measurement.t - previous_t
            if dt > 0:
                speed, rate = np.asarray(measurement.velocity, float)[:2]
                ends.append(measurement.t)
                durations.append(dt)
                values.append(np.array([speed * dt, 0.0, rate * dt]))
        previous_t = measurement.t
    if not values:
        raise InputError(f"{sequence.name}: no planar odometry to calibrate")
    return Increments(np.array(ends), np.array(durations), np.array(values))


def truth_reference(sequence: Sequence) -> Trajectory:
    """The sequence's true planar trajectory; ``InputError`` when it has none."""
    truth = None if sequence.ground_truth is None else sequence.ground_truth.pose
    if truth is None or len(truth.t) < 2:
        raise InputError(f"{sequence.name}: no ground-truth trajectory (use --reference smoother)")
    return truth
