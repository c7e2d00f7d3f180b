"""Benchmark suites: which datasets (with their ``--data`` options) meet which estimators
(with their ``--set`` options), and how many Monte Carlo runs by default.

The suites themselves are YAML files (``workbench.suite_files``: the built-in ones in
``workbench/suite_library/``: ``tiny`` for tests, ``quick`` the README's default, ``paper``,
``consistency``, ``calibration``); this module holds what a suite is once read.

A suite names what it *wants*; ``available_parts`` keeps what the registry has today and
returns a note for everything else, so a suite written for every estimator still runs while
some are missing (the note says which). Whether an estimator can run on a dataset (sensors,
dimension) is decided later, per pair, by ``workbench.sweep`` with ``runner.is_compatible``.
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

SHARED_DATA_PLACEHOLDER = "{shared}"
"""Stands for the folder of shared recordings in a dataset name (``shared_data_folder``)."""
SHARED_DATA_VARIABLE = "WORKBENCH_SHARED_DATA"


def shared_data_folder() -> Path:
    """Where ``{shared}`` points: ``$WORKBENCH_SHARED_DATA`` when set, else the first
    existing ``shared/data`` beside the working folder or beside the workbench's checkout
    (``../shared/data``), else the former (a dataset there is then skipped with a note)."""
    import os

    if os.environ.get(SHARED_DATA_VARIABLE):
        return Path(os.environ[SHARED_DATA_VARIABLE]).expanduser()
    candidates = [
        Path.cwd().parent / "shared" / "data",
        Path(__file__).resolve().parents[2] / "shared" / "data",
    ]
    return next((path for path in candidates if path.is_dir()), candidates[0])


def slug(text: str) -> str:
    """A file-name-safe form of ``text``: ``'sim:circle (ids=false)'`` -> ``'sim-circle-ids-false'``."""
    # leading dots stripped: a label '..' or '.hidden' must not name a parent or hidden folder
    name = re.sub(r"[^A-Za-z0-9._]+", "-", text)
    return re.sub(r"^[.-]+", "", name).rstrip("-") or "unnamed"


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
        generate: the name of a ``GENERATORS`` entry writing the file the dataset reads,
            called with the path the name points to before the sweep, when that file does
            not exist yet (the synthetic lidar bag).
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
        """The name with ``{data}`` replaced by ``data_folder`` and ``{shared}`` by
        ``shared_data_folder()``."""
        name = self.name.replace(DATA_FOLDER_PLACEHOLDER, str(data_folder))
        if SHARED_DATA_PLACEHOLDER in name:
            name = name.replace(SHARED_DATA_PLACEHOLDER, str(shared_data_folder()))
        return name


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
    reference: str | None = None
    """An estimator (registered name) every row's ATE is divided by, on the same dataset:
    the table's ``ATE ÷ ref`` column (``workbench.results.summary``)."""


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
    try:
        written = write_lidar_bag(scratch / path.name, 0, "ros1", {})
        for companion in scratch.iterdir():
            if companion != written:
                os.replace(companion, path.parent / companion.name)
        os.replace(written, path)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)  # a failed write leaves nothing behind


GENERATORS: dict[str, Callable[[Path], None]] = {"lidar-corridor": write_corridor_bag}
"""Files a suite can have written before its sweep (a dataset's ``generate``), by name."""


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


def with_settings(suite: Suite, settings: dict[str, dict[str, str]]) -> Suite:
    """The suite with ``--set`` options added to the estimators they name (after the
    suite's own). A changed estimator's label says what was set, so that its rows, figures
    and run folders never pass for the suite's own."""
    from dataclasses import replace

    def changed(spec: EstimatorSpec) -> EstimatorSpec:
        added = tuple(settings.get(spec.name, {}).items())
        if not added:
            return spec
        return replace(
            spec, overrides=spec.overrides + added, label=f"{spec.title} [{format_options(added)}]"
        )

    return replace(suite, estimators=tuple(changed(spec) for spec in suite.estimators))


def prepare_dataset(spec: DatasetSpec, data_folder: Path) -> None:
    """Generate the file a dataset reads (``spec.generate``) when it is not there yet."""
    if spec.generate is None:
        return
    _, _, argument = spec.resolved_name(data_folder).partition(":")
    path = Path(argument)
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        GENERATORS[spec.generate](path)


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
