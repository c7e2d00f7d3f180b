"""The smallest dataset the workbench loads: a planar robot on a straight line, its wheel
odometry (noisy relative poses) and the exact truth.

Copy it, then register it with one row in ``workbench/registry.py``:
``DatasetEntry("my-line", "my_package.module:load", "one line")``. It passes
``tests/test_estimator_conformance.py`` (which checks this file): ``load(argument, seed,
options)`` parses its ``--data`` options with ``parse_options`` (a misspelt key is an
error), draws every random number from the seed, returns a ``Sequence`` whose stream is
time-ordered and holds only the sensors it declares, with an initial state and the truth.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.measurements import Odometry, Sensor
from datasets.options import parse_options
from datasets.sequence import InitialState, Sequence
from datasets.state import GroundTruth, StateHistory
from datasets.trajectory import Trajectory


class LineOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")
    duration_s: float = Field(10.0, gt=0, le=3600, description="length of the run [s]")
    speed_m_s: float = Field(1.0, ge=0, description="forward speed [m/s]")
    rate_hz: float = Field(10.0, gt=0, le=1000, description="odometry rate [Hz]")
    sigma_m: float = Field(0.01, gt=0, description="odometry noise per increment and axis [m]")


def load(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """``my-line`` (no argument): the sequence of the module docstring."""
    if argument:
        raise InputError(f"my-line takes no argument, got '{argument}'")
    config = parse_options(LineOptions, options, "my-line --data")
    t = np.arange(int(config.duration_s * config.rate_hz) + 1) / config.rate_hz
    truth = Trajectory(t, np.column_stack([config.speed_m_s * t, 0 * t]), np.zeros(len(t)))
    rng = np.random.default_rng(seed)  # every random number from the seed
    step = config.speed_m_s / config.rate_hz
    noise = rng.normal(0.0, config.sigma_m, size=(len(t) - 1, 2))
    covariance = np.diag([config.sigma_m**2, config.sigma_m**2, 1e-8])
    increments = [
        Odometry(t=float(t[k + 1]), covariance=covariance, dt=1.0 / config.rate_hz,
                 relative_pose=np.array([step + noise[k, 0], noise[k, 1], 0.0]))
        for k in range(len(t) - 1)
    ]  # fmt: skip
    return Sequence(
        name="my-line",
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY}),
        stream=lambda: iter(increments),  # a fresh iterator per pass
        ground_truth=GroundTruth(history=StateHistory(pose=truth)),
        initial_state=InitialState(t=0.0, position=np.zeros(2), rotation=np.array(0.0)),
        metadata={"source": "examples/minimal_dataset.py", "seed": seed},
    )
