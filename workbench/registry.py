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
        describe_target="datasets.bags.source:describe",
    ),
    DatasetEntry(
        "scans",
        "datasets.scan_folder:load_scans",
        "folder of KITTI .bin / .pcd / .ply scans (optional times.txt): KISS-ICP odometry and corner landmarks",
        argument="FOLDER",
        examples=("scans:velodyne/",),
        describe_target="datasets.scan_folder:describe",
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
    """Load the ``Sequence`` called ``name`` with ``--data`` options."""
    entry = dataset_entry(name)
    _, argument = split_dataset_name(name)
    return entry.loader()(argument, seed, dict(options or {}))
