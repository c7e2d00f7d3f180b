"""The odometry noise model of the CARMEN logs.

There is no truth to fit it against. As for Victoria Park (``datasets.victoria_park``), it is
fitted against the batch smoother's estimate (odometry + the 2-D laser's corners), re-run
with each fit; unlike there, on the three shared logs at once (their 5 s windows pooled in
one maximum-likelihood fit, ``datasets.odometry_calibration.concatenate_windows``), so that
no log's quirks set it, and every log is then checked against the pooled model
(``benchmarks/bench_carmen.py --calibrate`` prints the fit and the check).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.odometry_noise import OdometryNoiseModel, read_model_file

CARMEN_ODOMETRY = OdometryNoiseModel(
    np.array(
        [
            [1e-5, 1e-5, 1e-5],  # per second: x [m^2/s], y [m^2/s], theta [rad^2/s]
            [1e-3, 1e-3, 1e-3],  # per metre: [m^2/m, m^2/m, rad^2/m]
            [1e-4, 1e-4, 5e-3],  # per radian turned: [m^2/rad, m^2/rad, rad^2/rad]
        ]
    ),
    "provisional",
)
"""The odometry noise of the shared CARMEN logs (module docstring)."""


def odometry_model(choice: str) -> OdometryNoiseModel:
    """The model ``--data odometry_noise=`` names: ``calibrated`` or a YAML file."""
    if choice == "calibrated":
        return CARMEN_ODOMETRY
    return read_model_file(Path(choice))
