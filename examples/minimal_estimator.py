"""The smallest estimator the workbench runs: planar odometry integrated with its covariance.

Copy it, then register it with one row in ``workbench/registry.py``:
``EstimatorEntry("my-odometry", "my_package.module:MinimalOdometry", "one line")``. It passes
``tests/test_estimator_conformance.py`` (which checks this file): a pydantic ``Config``,
``sensor_options`` and ``dimensions``, ``process`` fed in time order, ``estimate`` built by
``EstimateRecorder``, one pose per time with its covariance [x, y, theta] (GTSAM's Pose2
order, right perturbation). An estimator that uses landmarks also records one association
decision per sighting (``filters.association.policy`` decides them).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import Measurement, Odometry, Sensor
from datasets.rotations import rot2, wrap_angle
from datasets.sequence import Sequence


class MinimalOdometryConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")  # a misspelt --set key is an error
    odometry_noise_scale: float = Field(
        1.0, gt=0, description="multiplies the odometry covariance of the data"
    )


class MinimalOdometry:
    """Composes planar odometry increments: ``x' = x (+) u``, ``P' = F P F^T + G Q G^T``."""

    Config: ClassVar[type[BaseModel]] = MinimalOdometryConfig
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]] = (frozenset({Sensor.ODOMETRY}),)
    dimensions: ClassVar[frozenset[int]] = frozenset({2})

    def __init__(self, config: MinimalOdometryConfig, sequence: Sequence) -> None:
        start = sequence.initial_state  # the runner refuses sequences without one
        self.config = config
        self.pose = np.array([*start.position[:2], float(start.rotation)])
        self.covariance = np.diag([start.position_sigma_m**2] * 2 + [start.rotation_sigma_rad**2])
        self.recorder = EstimateRecorder(dimension=2)
        self.recorder.pose(start.t, self.pose[:2], self.pose[2], self.covariance)

    def process(self, measurement: Measurement) -> None:
        if not isinstance(measurement, Odometry) or measurement.relative_pose is None:
            return  # velocity samples, scans: not used by this template
        dx, dy, dtheta = measurement.relative_pose
        c, s = np.cos(dtheta), np.sin(dtheta)
        # right perturbation: the old error seen from the new frame (Ad of the increment's
        # inverse), then the increment's own noise
        jacobian = np.array([[c, s, s * dx - c * dy], [-s, c, c * dx + s * dy], [0, 0, 1]])
        noise = self.config.odometry_noise_scale * np.asarray(measurement.covariance, dtype=float)
        self.covariance = jacobian @ self.covariance @ jacobian.T + noise
        self.covariance = 0.5 * (self.covariance + self.covariance.T)
        self.pose[:2] += rot2(self.pose[2]) @ np.array([dx, dy])
        self.pose[2] = float(wrap_angle(self.pose[2] + dtheta))
        self.recorder.pose(measurement.t, self.pose[:2], self.pose[2], self.covariance)

    def estimate(self) -> Estimate:
        return self.recorder.build(notes=("odometry only: no landmark is used",))
