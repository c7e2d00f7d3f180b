"""Run one estimator on one sequence: resolve its config, check sensors, feed, time, collect.

Every estimator is timed the same way here (wall clock around each ``process`` call and
around the final ``estimate`` call), so cost columns are comparable across estimators.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import Estimate, Estimator, StepTiming, missing_sensors
from datasets.measurements import Sensor
from datasets.option_renames import renamed_options
from datasets.options import build_model, yaml_value
from datasets.sequence import Sequence
from datasets.yaml_files import read_yaml_file
from workbench.registry import estimator_entry, load_dataset

RUN_CONFIG_KEYS = frozenset({"estimator", "dataset", "seed", "config"})
"""The keys that make a YAML file a run folder's ``config.yaml`` (``run_folder``)."""


def resolve_config(
    estimator_class: type[Estimator],
    config_file: Path | None = None,
    overrides: dict[str, str] | None = None,
    name: str | None = None,
) -> BaseModel:
    """The estimator's config: class defaults, then the YAML file (estimator options, or a
    run folder's ``config.yaml``, whose resolved options it takes; read by
    ``datasets.yaml_files.read_yaml_file``: at most 1 MiB, UTF-8, no anchors, aliases or
    repeated keys), then ``--set`` overrides. An option under its name before issue 39
    (``datasets.option_renames``) is taken under its new name with a ``warning:`` line.
    ``name``: the estimator as registered, for errors and warnings."""
    values: dict[str, Any] = {}
    if config_file is not None:
        config_file = Path(config_file)
        if not config_file.is_file():
            raise InputError(f"{config_file}: no such config file")
        loaded = read_yaml_file(config_file) or {}
        if not isinstance(loaded, dict):
            raise InputError(f"{config_file}: expected a mapping of option: value")
        if RUN_CONFIG_KEYS <= set(loaded):
            # a run folder's config.yaml: its resolved estimator options
            loaded = loaded["config"] or {}
            if not isinstance(loaded, dict):
                raise InputError(
                    f"{config_file}: config: expected a mapping of option: value (the "
                    "estimator's resolved options)"
                )
        values.update(loaded)
    label = name or estimator_class.__name__
    fields = estimator_class.Config.model_fields
    # the file's old option names, then --set's: a --set under an old name overrides the
    # file's value under either name
    values, warnings = renamed_options(values, fields, label)
    given, more = renamed_options(
        {key: yaml_value(text) for key, text in (overrides or {}).items()}, fields, label
    )
    values.update(given)
    for line in warnings + more:
        _warn_once(line)
    # errors name the estimator as registered (ekf-slam), not its class (EkfSlam)
    return build_model(estimator_class.Config, values, f"{label} options")


_warned: set[str] = set()


def _warn_once(line: str) -> None:
    """One ``warning:`` line on stderr per renamed option and process (a sweep resolves the
    same options for every run)."""
    if line not in _warned:
        _warned.add(line)
        print(f"warning: {line}", file=sys.stderr)


@dataclass(frozen=True)
class RecordedRun:
    """What a run folder's ``config.yaml`` records of the run (besides the estimator's
    resolved options, which ``resolve_config`` takes from the same file)."""

    estimator: str
    dataset: str
    seed: int
    data_options: tuple[tuple[str, str], ...]


def recorded_run(config_file: Path) -> RecordedRun | None:
    """The run a ``config.yaml`` written by ``workbench run`` records, None for a file of
    estimator options only; ``InputError`` naming the file and field for one edited into
    something ``workbench run`` would not have written."""
    config_file = Path(config_file)
    if not config_file.is_file():
        raise InputError(f"{config_file}: no such config file")
    recorded = read_yaml_file(config_file) or {}
    if not isinstance(recorded, dict) or not RUN_CONFIG_KEYS <= set(recorded):
        return None
    for key in ("estimator", "dataset"):
        if not isinstance(recorded[key], str) or not recorded[key].strip():
            raise InputError(f"{config_file}: {key}: expected a name, got {recorded[key]!r}")
    seed = recorded["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(
            f"{config_file}: seed: expected a whole number >= 0 (as --seed takes it), got {seed!r}"
        )
    data_options = recorded.get("data_options") or {}
    if not isinstance(data_options, dict):
        raise InputError(
            f"{config_file}: data_options: expected a mapping of option: value, "
            f"got {data_options!r}"
        )
    if not isinstance(recorded["config"] or {}, dict):
        raise InputError(
            f"{config_file}: config: expected a mapping of option: value (the estimator's "
            "resolved options)"
        )
    return RecordedRun(
        recorded["estimator"],
        recorded["dataset"],
        seed,
        tuple((str(k), _option_text(v)) for k, v in data_options.items()),
    )


def _option_text(value: Any) -> str:
    """A recorded option value as the text ``--data key=TEXT`` gives (the loader parses
    it back to the same value)."""
    import json

    return value if isinstance(value, str) else json.dumps(value)


def check_compatible(
    estimator_name: str, estimator_class: type[Estimator], sequence: Sequence
) -> None:
    """``InputError`` naming the missing sensor(s) or the unsupported dimension."""
    missing = missing_sensors(estimator_class.sensor_options, sequence.sensors)
    if missing:
        names = " | ".join(
            "+".join(sorted(sensor.value for sensor in option))
            for option in estimator_class.sensor_options
        )
        provided = ", ".join(sorted(sensor.value for sensor in sequence.sensors)) or "none"
        raise InputError(
            f"estimator '{estimator_name}' needs sensor(s) {names}, which dataset '{sequence.name}' "
            f"does not provide (it provides: {provided})"
        )
    if sequence.dimension not in estimator_class.dimensions:
        raise InputError(
            f"estimator '{estimator_name}' does not support {sequence.dimension}-D dataset '{sequence.name}'"
        )


def is_compatible(estimator_class: type[Estimator], sequence: Sequence) -> bool:
    """Whether the estimator can run on the sequence (sensors and dimension)."""
    return not missing_sensors(estimator_class.sensor_options, sequence.sensors) and (
        sequence.dimension in estimator_class.dimensions
    )


def run_estimator(
    estimator_class: type[Estimator],
    config: BaseModel,
    sequence: Sequence,
    on_step: Callable[[float], None] | None = None,
) -> Estimate:
    """Feed the sequence to a fresh estimator and return its ``Estimate`` with timing. The
    estimator is built on a view of the sequence without its ground truth and without its
    front end's report."""
    # the estimator sees the data, never the truth it is scored against, nor the front end's
    # own poses it is compared with (Sequence.front_end)
    estimator = estimator_class(config, replace(sequence, ground_truth=None, front_end=None))
    stamps: list[float] = []
    seconds: list[float] = []
    frames: list[float] = []
    # a landmark scan is a frame only for an estimator that uses landmarks
    with_landmarks = any(Sensor.LANDMARKS in option for option in estimator_class.sensor_options)
    clock = time.perf_counter
    for measurement in sequence.measurements():
        start = clock()
        estimator.process(measurement)
        seconds.append(clock() - start)
        stamps.append(measurement.t)
        if is_frame(measurement, with_landmarks):
            frames.append(measurement.t)
        if on_step is not None:
            on_step(measurement.t)
    start = clock()
    estimate = estimator.estimate()
    finalize = clock() - start
    return replace(
        estimate,
        timing=StepTiming(np.array(stamps), np.array(seconds), finalize),
        frame_times=np.unique(np.array(frames, dtype=float)),
    )


def is_frame(measurement, with_landmarks: bool = True) -> bool:
    """A measurement after which the data expect a pose: a landmark scan that sighted
    something (``with_landmarks``: for an estimator that uses them), or a sensor frame's
    odometry increment (``Odometry.frame``: a lidar sweep, with or without corners); not a
    wheel-odometry or IMU sample."""
    from datasets.measurements import LandmarkScan, Odometry

    sighted = isinstance(measurement, LandmarkScan) and measurement.count > 0
    return (with_landmarks and sighted) or (isinstance(measurement, Odometry) and measurement.frame)


@dataclass(frozen=True)
class RunRequest:
    """Everything that defines one run (the resolved config is recorded in the run folder)."""

    estimator: str
    dataset: str
    seed: int = 0
    config_file: Path | None = None
    overrides: tuple[tuple[str, str], ...] = ()
    data_options: tuple[tuple[str, str], ...] = ()
    dataset_label: str = ""
    estimator_label: str = ""

    @property
    def labels(self) -> tuple[str, str]:
        """(dataset, estimator) names tables group by: a suite's labels, else the names."""
        return self.dataset_label or self.dataset, self.estimator_label or self.estimator


@dataclass(frozen=True)
class RunResult:
    request: RunRequest
    sequence: Sequence
    config: BaseModel
    estimate: Estimate


def execute(
    request: RunRequest,
    sequence: Sequence | None = None,
    on_step: Callable[[float], None] | None = None,
) -> RunResult:
    """Resolve names, load the dataset (unless given), check compatibility and run."""
    entry = estimator_entry(request.estimator)
    estimator_class = entry.load()
    config = resolve_config(
        estimator_class, request.config_file, dict(request.overrides), request.estimator
    )
    if sequence is None:
        sequence = load_dataset(request.dataset, request.seed, dict(request.data_options))
    check_compatible(request.estimator, estimator_class, sequence)
    estimate = run_estimator(estimator_class, config, sequence, on_step)
    return RunResult(request, sequence, config, estimate)
