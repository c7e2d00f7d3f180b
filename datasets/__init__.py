"""Data vocabulary, loaders, simulator and lidar front end.

Imports nothing from ``filters``, ``smoothers`` or ``workbench`` (DESIGN.md).
"""

from datasets.errors import InputError
from datasets.estimate import Diagnostics, Estimate, EstimateRecorder, Estimator, Event, StepTiming
from datasets.measurements import (
    GpsFix,
    GyroSample,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    PointCloud,
    Sensor,
)
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory

__all__ = [
    "BlockName",
    "Diagnostics",
    "Estimate",
    "EstimateRecorder",
    "Estimator",
    "Event",
    "Frame",
    "GpsFix",
    "GroundTruth",
    "GyroSample",
    "ImuSample",
    "InitialState",
    "InputError",
    "LandmarkMap",
    "LandmarkScan",
    "Measurement",
    "NoiseSpec",
    "Odometry",
    "PointCloud",
    "Sensor",
    "Sequence",
    "StateBlock",
    "StateHistory",
    "StepTiming",
    "Trajectory",
]
