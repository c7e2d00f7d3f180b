"""The explicit table of datasets and estimators.

Entries name their implementation as ``"module:attribute"`` and are imported on first use,
so that ``workbench list`` does not pay for importing GTSAM or KISS-ICP. The lower packages
know nothing of this table (DESIGN.md).

Dataset names: ``PREFIX`` or ``PREFIX:ARGUMENT`` (``sim:aghili-rover``,
``utias:FOLDER#robot1``, ``bag:PATH``). A dataset loader has the signature
``load(argument: str | None, seed: int, options: dict[str, str]) -> Sequence`` and rejects
unknown options with an ``InputError``; it exposes ``describe() -> list[str]`` lines for
``workbench list --verbose``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from datasets.errors import InputError, did_you_mean
from datasets.estimate import Estimator


def _resolve(target: str) -> Any:
    module_name, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module_name), attribute)


@dataclass(frozen=True)
class EstimatorEntry:
    """A registered estimator: name, ``module:Class`` implementing ``datasets.Estimator``."""

    name: str
    target: str
    summary: str

    def load(self) -> type[Estimator]:
        """The estimator class (``tests/test_estimator_conformance.py`` checks that every
        registered one honours the protocol)."""
        return _resolve(self.target)


@dataclass(frozen=True)
class DatasetEntry:
    """A registered dataset family: prefix, ``module:function`` loader, and help text.

    ``argument`` says what follows ``PREFIX:`` (None when the name takes no argument).
    ``examples`` are full dataset names listed by ``workbench list``.
    """

    prefix: str
    target: str
    summary: str
    argument: str | None = None
    examples: tuple[str, ...] = ()
    describe_target: str | None = None

    def loader(self) -> Callable[..., Any]:
        return _resolve(self.target)

    def describe(self) -> list[str]:
        return list(_resolve(self.describe_target)()) if self.describe_target else []


ESTIMATORS: tuple[EstimatorEntry, ...] = (
    EstimatorEntry(
        "dead-reckoning",
        "filters.dead_reckoning:DeadReckoning",
        "strap-down IMU / odometry / gyro integration without corrections (the lower bound)",
    ),
    EstimatorEntry(
        "aghili",
        "filters.aghili.filter:AghiliFilter",
        "Aghili adaptive error-state EKF SLAM: strap-down IMU + 3-D landmarks, r known anchors, IMU biases, adaptive R (eq. 42)",
    ),
    EstimatorEntry(
        "sensor-based",
        "filters.sensor_based.filter:SensorBasedSlam",
        "Guerreiro et al. 2013 GAS sensor-based (robocentric LTV Kalman) SLAM: gyro + body-frame landmarks, JCBB",
    ),
    EstimatorEntry(
        "ekf-slam",
        "filters.ekf_slam.filter:EkfSlam",
        "world-centric EKF-SLAM baseline (odometry or gyro + constant velocity; ids or JCBB; Joseph form)",
    ),
    EstimatorEntry(
        "ekf-slam-mht",
        "filters.ekf_slam.multi_hypothesis:MultiHypothesisEkfSlam",
        "ekf-slam keeping the most likely association hypotheses (multiple hypothesis tracking) where scans have no ids",
    ),
    EstimatorEntry(
        "smoother-batch",
        "smoothers.modes:SmootherBatch",
        "GTSAM batch Levenberg-Marquardt over IMU-preintegration keyframes + landmarks (2-D: Pose2/Point2), started from an iSAM2 pass: the reference",
    ),
    EstimatorEntry(
        "smoother-isam2",
        "smoothers.modes:SmootherIsam2",
        "GTSAM iSAM2 over IMU-preintegration keyframes + landmarks/GPS (2-D: Pose2/Point2); causal = after each keyframe",
    ),
    EstimatorEntry(
        "smoother-fixed-lag",
        "smoothers.modes:SmootherFixedLag",
        "GTSAM IncrementalFixedLagSmoother (window lag_s) over the same keyframe graph",
    ),
)

DATASETS: tuple[DatasetEntry, ...] = (
    DatasetEntry(
        "sim",
        "datasets.simulation.scenarios:load_scenario",
        "seeded simulator with exact ground truth",
        argument="SCENARIO",
        examples=("sim:aghili-rover", "sim:guerreiro-loop", "sim:circle", "sim:static"),
        describe_target="datasets.simulation.scenarios:describe_scenarios",
    ),
    DatasetEntry(
        "utias",
        "datasets.utias:load",
        "UTIAS MRCLAM real 2-D data: odometry, barcode range/bearing, Vicon truth of poses and landmarks",
        argument="FOLDER#robotN",
        examples=("utias:../shared/data/utias-mrclam1#robot1",),
        describe_target="datasets.utias:describe",
    ),
    DatasetEntry(
        "victoria-park",
        "datasets.victoria_park:load",
        "Victoria Park (gtsam Data): odometry increments and tree landmarks, nominal 0.2 s step, no truth",
        examples=("victoria-park",),
        describe_target="datasets.victoria_park:describe",
    ),
    DatasetEntry(
        "kitti-imu-gps",
        "datasets.kitti_imu_gps:load",
        "KITTI IMU (100 Hz) + GPS (1 Hz) from gtsam Data; a seeded fraction of fixes held out for gps_holdout_rmse_m",
        examples=("kitti-imu-gps",),
        describe_target="datasets.kitti_imu_gps:describe",
    ),
    DatasetEntry(
        "bag",
        "datasets.bags.source:load_bag",
        "ROS 1 .bag / ROS 2 bag (sqlite3, mcap): clouds, IMU, GPS; KISS-ICP odometry and corner landmarks; truth from an Odometry/PoseStamped topic",
        argument="PATH",
        examples=("bag:corridor.bag",),
        describe_target="datasets.bags.bag_options:describe",
    ),
    DatasetEntry(
        "scans",
        "datasets.scan_folder:load_scans",
        "folder of KITTI .bin / .pcd / .ply scans (optional times.txt): KISS-ICP odometry and corner landmarks",
        argument="FOLDER",
        examples=("scans:velodyne/",),
        describe_target="datasets.scan_folder:describe",
    ),
    DatasetEntry(
        "carmen",
        "datasets.carmen:load",
        "CARMEN .clf[.bz2] 2-D laser log (FLASER/RLASER/ROBOTLASER1, ODOM): wheel odometry and split-and-merge corner landmarks without ids, no truth",
        argument="FILE",
        examples=("carmen:../shared/data/carmen-logs/intel.clf.bz2",),
        describe_target="datasets.carmen:describe",
    ),
)


def estimator_entry(name: str) -> EstimatorEntry:
    """The estimator called ``name``; ``InputError`` listing the known ones otherwise."""
    for entry in ESTIMATORS:
        if entry.name == name:
            return entry
    names = [entry.name for entry in ESTIMATORS]
    raise InputError(
        f"unknown estimator '{name}'{did_you_mean(name, names)} (known: {', '.join(names)})"
    )


def split_dataset_name(name: str) -> tuple[str, str | None]:
    """``'sim:circle'`` -> ``('sim', 'circle')``; ``'victoria-park'`` -> ``('victoria-park', None)``."""
    prefix, separator, argument = name.partition(":")
    return prefix, (argument if separator else None)


def dataset_entry(name: str) -> DatasetEntry:
    """The dataset family of ``name``; ``InputError`` listing the known ones otherwise."""
    prefix, argument = split_dataset_name(name)
    for entry in DATASETS:
        if entry.prefix == prefix:
            if entry.argument is not None and not argument:
                raise InputError(f"dataset '{name}' needs an argument: {prefix}:{entry.argument}")
            if entry.argument is None and argument:
                raise InputError(f"dataset '{prefix}' takes no argument (got '{name}')")
            return entry
    known = ", ".join(
        entry.prefix + (f":{entry.argument}" if entry.argument else "") for entry in DATASETS
    )
    hint = did_you_mean(prefix, [entry.prefix for entry in DATASETS])
    raise InputError(f"unknown dataset '{name}'{hint} (known: {known})")


def load_dataset(name: str, seed: int, options: dict[str, str] | None = None):
    """Load the ``Sequence`` called ``name`` with ``--data`` options.

    Two options belong to no loader and every dataset: ``relations=FILE`` (relative poses
    between pairs of times, scored by ``workbench.metrics.relations``) and
    ``relations_max_diff_s=S`` (their stamp tolerance [s]). They are taken out of the options
    before the loader parses the rest (loaders forbid unknown keys), the file is read, and
    the relations are attached to the sequence's ``GroundTruth.relations`` with
    ``dataclasses.replace`` (a sequence without truth gets a truth holding only them).
    Why here: relations are evaluation data a user brings for any recording (the CARMEN
    logs, a bag, a simulation), not something a loader knows or decodes; one hook keeps
    every loader, present and future, free of the option, while the relations still travel
    with the ``Sequence`` into ``compute_metrics`` (metrics.json, tables), and
    ``config.yaml`` records them with the other ``--data`` options, so ``rerun`` repeats
    them. The file is read before the loader runs, so a bad file fails fast.
    """
    entry = dataset_entry(name)
    _, argument = split_dataset_name(name)
    remaining = dict(options or {})
    relations = _read_relations_options(
        remaining.pop("relations", None), remaining.pop("relations_max_diff_s", None)
    )
    sequence = entry.loader()(argument, seed, remaining)
    if relations is None:
        return sequence
    from dataclasses import replace

    from datasets.state import GroundTruth, StateHistory

    truth = sequence.ground_truth or GroundTruth(history=StateHistory())
    return replace(sequence, ground_truth=replace(truth, relations=relations))


def _read_relations_options(path: str | None, max_diff_s: str | None):
    """``Relations`` from ``--data relations=FILE [relations_max_diff_s=S]``, or None."""
    if path is None:
        if max_diff_s is not None:
            raise InputError("--data relations_max_diff_s needs --data relations=FILE")
        return None
    if not path:
        raise InputError("--data relations= needs a file: relations=FILE")
    import math

    tolerance = None
    if max_diff_s is not None:
        try:
            tolerance = float(max_diff_s)
        except ValueError:
            tolerance = math.nan
        if not (tolerance > 0 and math.isfinite(tolerance)):
            raise InputError(
                f"--data relations_max_diff_s must be a positive number of seconds, "
                f"got '{max_diff_s}'"
            )
    from workbench.metrics.relations import read_relations

    try:
        return read_relations(path, tolerance)
    except InputError as error:
        raise InputError(f"--data relations: {error}") from None
