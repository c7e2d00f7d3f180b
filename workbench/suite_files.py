"""Suites as YAML files: the built-in ones in ``workbench/suite_library/`` and any file a
user copies and edits (``workbench suite quick > mine.yaml``, ``workbench bench mine.yaml``).

A suite file (the suite's name is the file's stem)::

    description: what it is for (one line)
    runs: 3                      # Monte Carlo runs per pair unless --runs says otherwise
    reference: smoother-isam2    # optional: every ATE over this estimator's, per dataset
    table: consistency           # optional: the LaTeX tables a report writes by default
                                 # (accuracy, consistency, cost, all, or table.csv columns
                                 # COL,COL; --table overrides it; default all)
    datasets:
      - sim:circle               # a name alone, or:
      - name: sim:guerreiro-loop # as `workbench run` takes it; {data}: the sweep's OUT/data,
                                 # {shared}: $WORKBENCH_SHARED_DATA or ../shared/data
        data: {duration_s: 20}   # --data options
        label: loop (20 s)       # its name in tables, plots and folders (default: name)
        seeded: true             # false for a recording: run once whatever --runs says
        generate: lidar-corridor # write the file the name points to before the sweep
        set:                     # --set options this dataset adds for an estimator
          sensor-based: {tuning: paper}
        left_out:                # estimators this suite does not run here, and why
          smoother-batch: too slow for this suite
    estimators:
      - ekf-slam                 # a name alone, or:
      - name: ekf-slam
        label: ekf-slam (slow walk)
        set: {velocity_walk_m_s_sqrt_s: 0.05}

Option values are YAML (numbers, booleans, lists, null) and reach the estimator and the
loader exactly as the same text after ``--set``/``--data`` would. Keys are checked: a
misspelt key is an error naming the file and the key, not a silent default.
"""

from __future__ import annotations

import json
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, field_validator

from datasets.errors import InputError, did_you_mean
from datasets.options import build_model
from datasets.yaml_files import read_yaml_file
from workbench.suites import GENERATORS, DatasetSpec, EstimatorSpec, Options, Suite

SUITE_LIBRARY = Path(__file__).resolve().parent / "suite_library"
DEFAULT_SUITE = "quick"

OptionValue = str | int | float | bool | None | list


def option_text(value: OptionValue) -> str:
    """A YAML option value as the text ``--set key=TEXT`` would carry (strings as they are,
    everything else as JSON, which the option parser reads back as the same value)."""
    return value if isinstance(value, str) else json.dumps(value)


def _options(values: dict[str, OptionValue]) -> Options:
    return tuple((str(key), option_text(value)) for key, value in values.items())


class _EstimatorEntry(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str
    label: str = ""
    set: dict[str, OptionValue] = Field(default_factory=dict)


class _DatasetEntry(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str
    data: dict[str, OptionValue] = Field(default_factory=dict)
    label: str = ""
    seeded: bool = True
    generate: str | None = None
    set: dict[str, dict[str, OptionValue]] = Field(default_factory=dict)
    left_out: dict[str, str] = Field(default_factory=dict)

    @field_validator("generate")
    @classmethod
    def _known_generator(cls, value: str | None) -> str | None:
        if value is not None and value not in GENERATORS:
            raise ValueError(f"unknown generator '{value}' (known: {', '.join(GENERATORS)})")
        return value


class _SuiteFile(BaseModel):
    model_config = ConfigDict(extra="forbid")

    description: str = ""
    runs: int = Field(default=3, ge=1)
    datasets: list[str | _DatasetEntry] = Field(min_length=1)
    estimators: list[str | _EstimatorEntry] = Field(min_length=1)
    reference: str | None = None
    table: str | None = None

    @field_validator("table")
    @classmethod
    def _known_table(cls, value: str | None) -> str | None:
        from workbench.results.columns import parse_table_choice

        if value is not None:
            try:
                parse_table_choice(value, "table")
            except InputError as error:
                raise ValueError(str(error)) from None
        return value


def _dataset_spec(entry: str | _DatasetEntry) -> DatasetSpec:
    if isinstance(entry, str):
        return DatasetSpec(entry)
    return DatasetSpec(
        entry.name,
        _options(entry.data),
        label=entry.label,
        seeded=entry.seeded,
        generate=entry.generate,
        left_out=tuple(entry.left_out.items()),
        estimator_options=tuple((name, _options(values)) for name, values in entry.set.items()),
    )


def _estimator_spec(entry: str | _EstimatorEntry) -> EstimatorSpec:
    if isinstance(entry, str):
        return EstimatorSpec(entry)
    return EstimatorSpec(entry.name, _options(entry.set), label=entry.label)


def load_suite_file(path: Path) -> Suite:
    """The suite a YAML file describes; ``InputError`` naming the file and the bad key.
    Read by ``datasets.yaml_files.read_yaml_file``: at most 1 MiB (checked before parsing),
    UTF-8, no anchors or aliases (a few bytes of aliases would expand to gigabytes of suite)
    and no key written twice."""
    path = Path(path)
    try:
        values = read_yaml_file(path)
    except OSError as error:
        raise InputError(f"{path}: cannot read the suite file ({error.strerror})") from None
    except InputError as error:
        raise InputError(f"not a YAML suite file: {error}") from None
    if not isinstance(values, dict):
        raise InputError(
            f"{path}: a suite file is a YAML mapping (description, runs, datasets, estimators)"
        )
    parsed = build_model(_SuiteFile, values, f"suite file {path}")
    datasets = tuple(_dataset_spec(entry) for entry in parsed.datasets)
    estimators = tuple(_estimator_spec(entry) for entry in parsed.estimators)
    for kind, specs in (("dataset", datasets), ("estimator", estimators)):
        titles = [spec.title for spec in specs]
        repeated = sorted({title for title in titles if titles.count(title) > 1})
        if repeated:
            raise InputError(
                f"{path}: {kind} {', '.join(repeated)} listed twice: give each a label of its own"
            )
    if parsed.reference is not None and parsed.reference not in {s.name for s in estimators}:
        raise InputError(
            f"{path}: reference '{parsed.reference}' is not one of the suite's estimators "
            f"({', '.join(spec.name for spec in estimators)})"
        )
    return Suite(path.stem, parsed.description, datasets, estimators, parsed.runs, parsed.reference)


def suite_table(name_or_path: str) -> str:
    """The LaTeX tables a suite's report writes by default: its file's ``table:``, else
    ``all``. Read after ``get_suite`` has checked the file."""
    from workbench.results.columns import DEFAULT_TABLE

    path = suite_path(name_or_path)
    parsed = build_model(_SuiteFile, read_yaml_file(path), f"suite file {path}")
    return parsed.table or DEFAULT_TABLE


def builtin_suites() -> list[str]:
    """Names of the suites that ship with the workbench, in the order ``list`` shows them."""
    order = ["tiny", "quick", "paper", "consistency", "calibration", "real"]
    found = sorted(path.stem for path in SUITE_LIBRARY.glob("*.yaml"))
    return [name for name in order if name in found] + [n for n in found if n not in order]


def suite_path(name_or_path: str) -> Path:
    """The file of a built-in suite name, or the path itself when it names a YAML file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.is_file():
        if not path.is_file():
            raise InputError(f"{path}: no such suite file")
        return path
    builtin = SUITE_LIBRARY / f"{name_or_path}.yaml"
    if not builtin.is_file():
        known = builtin_suites()
        raise InputError(
            f"unknown suite '{name_or_path}'{did_you_mean(name_or_path, known)} (built in: "
            f"{', '.join(known)}; or the path of a suite .yaml file)"
        )
    return builtin


def get_suite(name_or_path: str) -> Suite:
    """A built-in suite by name, or the suite in a YAML file."""
    return load_suite_file(suite_path(name_or_path))
