"""Benchmark suites: which datasets (with their ``--data`` options) meet which estimators
(with their ``--set`` options), and how many Monte Carlo runs by default.

A suite names what it *wants*; ``available_parts`` keeps what the registry has today and
returns a note for everything else, so a suite written for every estimator still runs while
some are missing (the note says which). Whether an estimator can run on a dataset (sensors,
dimension) is decided later, per pair, by ``workbench.sweep`` with ``runner.is_compatible``.

Suites:
    ``tiny``         tests: seconds. Two very short simulated scenarios, dead reckoning and
                     one fast filter.
    ``quick``        the README's default (``workbench bench``): the simulated scenarios,
                     shortened, plus the real data inside the gtsam wheel (Victoria Park,
                     KITTI IMU/GPS), shortened through their ``--data`` options, every
                     estimator; under 2 minutes with 3 runs on 2 cores.
    ``paper``        the two papers' scenarios at full length, Victoria Park, KITTI IMU/GPS
                     and the synthetic lidar bag, every estimator.
    ``consistency``  Monte Carlo NEES: the simulated scenarios (the rover's first minute,
                     the whole loop, the loop with a random speed, half a minute of the
                     circle), 50 runs.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from datasets.errors import InputError
from workbench.registry import ESTIMATORS, dataset_entry

Options = tuple[tuple[str, str], ...]
"""``key=value`` pairs in a fixed order (hashable, picklable, deterministic)."""

DATA_FOLDER_PLACEHOLDER = "{data}"
"""Stands for ``OUT/data`` in a dataset name (files a suite generates before the sweep)."""


def slug(text: str) -> str:
    """A file-name-safe form of ``text``: ``'sim:circle (ids=false)'`` -> ``'sim-circle-ids-false'``."""
    return re.sub(r"[^A-Za-z0-9._]+", "-", text).strip("-") or "unnamed"


def format_options(options: Options) -> str:
    """``(('a', '1'), ('b', 'x'))`` -> ``'a=1 b=x'``."""
    return " ".join(f"{key}={value}" for key, value in options)


@dataclass(frozen=True)
class DatasetSpec:
    """One dataset of a suite.

    Attributes:
        name: dataset name as ``workbench run`` takes it (``sim:circle``, ``victoria-park``);
            ``{data}`` stands for the sweep's ``OUT/data`` folder.
        options: ``--data`` options.
        label: the name in tables, plots and folder names (default: ``name``); two specs of
            one dataset with different options need different labels.
        seeded: False for a recording: it is run once (seed 0) whatever ``--runs`` says,
            since more runs would repeat the same measurements (for ``kitti-imu-gps`` the seed
            only picks which GPS fixes are held out).
        generate: ``"module:function"`` writing the file the dataset reads, called as
            ``function(path: Path)`` with the path the name points to, before the sweep,
            when that file does not exist yet (the synthetic lidar bag).
        left_out: ``(estimator name, reason)`` pairs this suite does not run on this
            dataset although they could (too slow for the suite's budget); the table says
            n/a with the reason.
        estimator_options: ``(estimator name, --set options)`` pairs that this dataset
            needs (added after the estimator's own), e.g. anchors from the first
            observation where the dataset has no surveyed landmarks.
    """

    name: str
    options: Options = ()
    label: str = ""
    seeded: bool = True
    generate: str | None = None
    left_out: tuple[tuple[str, str], ...] = ()
    estimator_options: tuple[tuple[str, Options], ...] = ()

    def options_for(self, estimator: str) -> Options:
        """The ``--set`` options this dataset adds for ``estimator``."""
        return tuple(
            option
            for name, options in self.estimator_options
            if name == estimator
            for option in options
        )

    def left_out_reason(self, estimator: str) -> str | None:
        for name, reason in self.left_out:
            if name == estimator:
                return f"left out of this suite: {reason}"
        return None

    @property
    def title(self) -> str:
        return self.label or self.name

    @property
    def folder_name(self) -> str:
        return slug(self.title)

    def resolved_name(self, data_folder: Path) -> str:
        """The name with ``{data}`` replaced by ``data_folder``."""
        return self.name.replace(DATA_FOLDER_PLACEHOLDER, str(data_folder))


@dataclass(frozen=True)
class EstimatorSpec:
    """One estimator of a suite: registered name, ``--set`` options, label (default: name)."""

    name: str
    overrides: Options = ()
    label: str = ""

    @property
    def title(self) -> str:
        return self.label or self.name

    @property
    def folder_name(self) -> str:
        return slug(self.title)


@dataclass(frozen=True)
class Suite:
    """A named set of datasets and estimators, and the default number of runs per cell."""

    name: str
    description: str
    datasets: tuple[DatasetSpec, ...]
    estimators: tuple[EstimatorSpec, ...]
    default_runs: int = 3


# Every estimator the workbench is meant to have, in table order: the lower bound first,
# then the filters, then the smoothers (the reference).
ALL_ESTIMATORS: tuple[EstimatorSpec, ...] = (
    EstimatorSpec("dead-reckoning"),
    EstimatorSpec("aghili"),
    EstimatorSpec("sensor-based"),
    EstimatorSpec("ekf-slam"),
    EstimatorSpec("smoother-isam2"),
    EstimatorSpec("smoother-fixed-lag"),
    EstimatorSpec("smoother-batch"),
)


def write_corridor_bag(path: Path) -> None:
    """The synthetic lidar corridor as a ROS 1 bag at ``path`` (seed 0, default options),
    with its corner sidecar beside it.

    Written in a scratch folder and moved into place bag last, so that a killed sweep never
    leaves a partial bag that the next one would take for a finished one. The bag is a
    fixed recording: every run reads the same file (``seeded=False``)."""
    import os
    import shutil

    from datasets.synthetic_lidar import write_lidar_bag

    path = Path(path)
    scratch = path.parent / f".partial-{path.name}"
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir(parents=True)
    written = write_lidar_bag(scratch / path.name, 0, "ros1", {})
    for companion in scratch.iterdir():
        if companion != written:
            os.replace(companion, path.parent / companion.name)
    os.replace(written, path)
    shutil.rmtree(scratch, ignore_errors=True)


def gyro_walk_options(walk: str) -> tuple[tuple[str, Options], ...]:
    """Every gyro-driven estimator told the body-velocity random walk ``walk`` ("[forward,
    lateral]" [m/s/sqrt(s)]) and, for the sensor-based filter, static landmarks."""
    return (
        ("dead-reckoning", (("gyro_velocity_sigma_m_s2", walk),)),
        ("ekf-slam", (("acceleration_density", walk),)),
        ("sensor-based", (("sigma_velocity_m_s", walk), ("sigma_landmark_m", "0"))),
        ("smoother-isam2", (("planar_velocity_walk_m_s2", walk),)),
        ("smoother-fixed-lag", (("planar_velocity_walk_m_s2", walk),)),
        ("smoother-batch", (("planar_velocity_walk_m_s2", walk),)),
    )


MATCHED_LOOP_WALK = "[0.01, 0.0025]"
"""The model-matched loop's body-velocity walk: half the calibration's, so that a 120 s
walk keeps away from zero speed and from the end of the path on every seed (checked for
seeds 0-49 over 100 s)."""
MATCHED_LOOP_DATA: Options = (
    ("duration_s", "100"),
    ("speed_profile", "random"),
    ("speed_reversion_s", "null"),
    ("speed_walk_m_s_sqrt_s", "0.01"),
    ("lateral_walk_m_s_sqrt_s", "0.0025"),
)

SUITES: dict[str, Suite] = {
    suite.name: suite
    for suite in (
        Suite(
            "tiny",
            "for tests: two very short simulated scenarios, dead reckoning and one fast filter (seconds)",
            datasets=(
                DatasetSpec("sim:circle", (("duration_s", "4"),)),
                DatasetSpec("sim:guerreiro-loop", (("duration_s", "8"),)),
            ),
            estimators=(EstimatorSpec("dead-reckoning"), EstimatorSpec("ekf-slam")),
            default_runs=2,
        ),
        Suite(
            "quick",
            "the default: shortened simulated scenarios and the gtsam wheel's real data, every estimator (< 2 min, 3 runs, 2 cores)",
            datasets=(
                DatasetSpec("sim:aghili-rover", (("duration_s", "10"),)),
                DatasetSpec("sim:guerreiro-loop", (("duration_s", "20"),)),
                DatasetSpec(
                    "victoria-park",
                    (("max_steps", "1000"),),
                    seeded=False,
                ),
                DatasetSpec("kitti-imu-gps", (("duration_s", "60"),), seeded=False),
            ),
            estimators=ALL_ESTIMATORS,
            default_runs=3,
        ),
        Suite(
            "paper",
            "the papers' scenarios at full length, Victoria Park, KITTI IMU/GPS, the synthetic lidar bag; every estimator",
            datasets=(
                DatasetSpec("sim:aghili-rover"),
                DatasetSpec(
                    "sim:guerreiro-loop",
                    (("ids", "false"),),
                    label="sim:guerreiro-loop (ids=false)",
                    # the paper's own filter tuning, on the laser's own noise
                    estimator_options=(("sensor-based", (("tuning", "paper"),)),),
                ),
                DatasetSpec(
                    "victoria-park",
                    (("ids", "false"),),
                    label="victoria-park (ids=false)",
                    seeded=False,
                ),
                DatasetSpec("kitti-imu-gps", seeded=False),
                DatasetSpec(
                    "bag:{data}/lidar-corridor.bag",
                    label="bag:lidar-corridor",
                    seeded=False,
                    generate="workbench.suites:write_corridor_bag",
                    # no surveyed corners in a bag: Aghili's anchors from their first sighting
                    estimator_options=(("aghili", (("anchor_source", "first-observation"),)),),
                ),
            ),
            estimators=ALL_ESTIMATORS,
            default_runs=3,
        ),
        Suite(
            "consistency",
            "Monte Carlo NEES of the papers' scenarios at the papers' tunings and at model-matched "
            "tunings, and the circle (50 runs)",
            datasets=(
                # the papers' tunings: every estimator's defaults (Aghili's adaptive R on)
                DatasetSpec("sim:aghili-rover", (("duration_s", "60"),)),
                DatasetSpec("sim:guerreiro-loop"),
                # model-matched: Aghili's R the scans' own; the loop's motion drawn from the
                # gyro-driven models (body-velocity random walk per axis) for 100 s, which every
                # gyro-driven estimator is told
                DatasetSpec(
                    "sim:aghili-rover",
                    (("duration_s", "60"),),
                    label="sim:aghili-rover (model-matched)",
                    estimator_options=(("aghili", (("adaptive_noise", "false"),)),),
                ),
                DatasetSpec(
                    "sim:guerreiro-loop",
                    MATCHED_LOOP_DATA,
                    label="sim:guerreiro-loop (model-matched)",
                    estimator_options=gyro_walk_options(MATCHED_LOOP_WALK),
                ),
                DatasetSpec("sim:circle", (("duration_s", "30"),)),
            ),
            estimators=ALL_ESTIMATORS,
            default_runs=50,
        ),
    )
}

CIRCLE_CALIBRATION = DatasetSpec(
    "sim:circle",
    (("duration_s", "10"),),
    label="sim:circle (calibration)",
    # constant speed on a circle: the body velocity of the gyro-driven models is constant,
    # so their velocity process noise is set near zero (the truth has none); Aghili's R is
    # the scans' own (adaptive R estimates it from a window: its sampling error alone reads
    # NIS 1.013, optimistic against a band of +-1.3 %, on this scenario)
    estimator_options=(
        ("aghili", (("adaptive_noise", "false"),)),
        ("ekf-slam", (("acceleration_density", "0.001"),)),
        ("sensor-based", (("sigma_velocity_m_s", "0.001"), ("sigma_landmark_m", "0"))),
    ),
)
LOOP_VELOCITY_WALK = "[0.02, 0.005]"
"""Body-velocity random walk [forward, lateral] of the calibration loop [m/s/sqrt(s)]."""
LOOP_CALIBRATION = DatasetSpec(
    "sim:guerreiro-loop",
    (
        ("duration_s", "20"),
        ("speed_profile", "random"),
        ("speed_reversion_s", "null"),
        ("speed_walk_m_s_sqrt_s", "0.02"),
        ("lateral_walk_m_s_sqrt_s", "0.005"),
        ("landmark_noise", "cartesian"),
    ),
    label="sim:guerreiro-loop (calibration)",
    # the body velocity is a random walk per axis (forward 0.02, lateral 0.005 m/s/sqrt(s):
    # the vehicle slips a little), the laser noise Cartesian: every gyro-driven model is
    # told exactly that
    estimator_options=gyro_walk_options(LOOP_VELOCITY_WALK),
)
SUITES["calibration"] = Suite(
    "calibration",
    "the workbench's self-test: every estimator on short scenarios drawn exactly from its own "
    "model (25 runs); a consistent estimator reads 'consistent' in every cell it fills",
    datasets=(CIRCLE_CALIBRATION, LOOP_CALIBRATION),
    estimators=ALL_ESTIMATORS,
    default_runs=25,
)

DEFAULT_SUITE = "quick"


def get_suite(name: str) -> Suite:
    """The suite called ``name``; ``InputError`` listing the known ones otherwise."""
    try:
        return SUITES[name]
    except KeyError:
        raise InputError(f"unknown suite '{name}' (known: {', '.join(SUITES)})") from None


def restrict(
    suite: Suite, datasets: list[str] | None = None, estimators: list[str] | None = None
) -> Suite:
    """The suite with only the named datasets (name or label) and estimators (name or
    label); ``InputError`` for a name the suite does not have."""
    from dataclasses import replace

    def keep(specs: tuple, wanted: list[str] | None, kind: str) -> tuple:
        if not wanted:
            return specs
        known = {spec.name for spec in specs} | {spec.title for spec in specs}
        unknown = [name for name in wanted if name not in known]
        if unknown:
            raise InputError(
                f"suite '{suite.name}' has no {kind} {', '.join(unknown)} (it has: {', '.join(spec.title for spec in specs)})"
            )
        titles = {spec.title for spec in specs}

        def chosen(spec) -> bool:
            # a title picks that spec only; a name without a spec titled so picks all of it
            return spec.title in wanted or (spec.name in wanted and spec.name not in titles)

        return tuple(spec for spec in specs if chosen(spec))

    return replace(
        suite,
        datasets=keep(suite.datasets, datasets, "dataset"),
        estimators=keep(suite.estimators, estimators, "estimator"),
    )


def _resolve_callable(target: str) -> Callable[..., object]:
    import importlib

    module_name, _, attribute = target.partition(":")
    return getattr(importlib.import_module(module_name), attribute)


def prepare_dataset(spec: DatasetSpec, data_folder: Path) -> None:
    """Generate the file a dataset reads (``spec.generate``) when it is not there yet."""
    if spec.generate is None:
        return
    _, _, argument = spec.resolved_name(data_folder).partition(":")
    path = Path(argument)
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        _resolve_callable(spec.generate)(path)


def available_parts(
    suite: Suite,
) -> tuple[tuple[DatasetSpec, ...], tuple[EstimatorSpec, ...], tuple[str, ...]]:
    """The suite's datasets and estimators that are registered today, and a note for each
    one that is not (skipped, not an error: other parts of the workbench may add it later)."""
    registered = {entry.name for entry in ESTIMATORS}
    estimators = tuple(spec for spec in suite.estimators if spec.name in registered)
    notes = [
        f"estimator '{spec.name}' is not registered: skipped"
        for spec in suite.estimators
        if spec.name not in registered
    ]
    datasets = []
    for spec in suite.datasets:
        try:
            dataset_entry(spec.name)
        except InputError as error:
            notes.append(f"dataset '{spec.title}' skipped: {error}")
            continue
        datasets.append(spec)
    return tuple(datasets), estimators, tuple(notes)
