"""One table row, one experiment: runs that share labels but differ in anything besides
their seed are separate rows, labelled by what differs.

A run is identified by its dataset (resolved name and options), its estimator's resolved
config, its seed and the code's revision (``RunRecord.experiment`` holds all but the seed).
A mean over runs of different experiments is a wrong number (``workbench report`` once put
a 5 s and a 4 s ``sim:circle`` into one "ekf-slam, 3 runs" row), so ``split_experiments``
gives each experiment its own labels: dataset options and the dataset's name go to the
dataset label (``sim:circle [duration_s=5]``), estimator options and the revision to the
estimator label (``ekf-slam [gate_probability=0.95]``, ``ekf-slam [rev 1a2b3c4]``). Two
runs of one experiment with the same seed are the same run twice: an error naming both.
"""

from __future__ import annotations

from dataclasses import replace

from datasets.errors import InputError
from workbench.results.runs import RunRecord

Experiment = tuple[tuple[str, str], ...]


def _name(key: str) -> str:
    """``data.duration_s`` -> ``duration_s``; ``revision`` -> ``revision``."""
    return key.split(".", 1)[1] if "." in key else key


def _shown(key: str, value: str | None) -> str:
    if key == "revision":
        return f"rev {value[:9] if value else 'unknown'}"
    return f"{_name(key)}={'(default)' if value is None else value}"


def _labels(record: RunRecord, experiment: Experiment, differing: list[str]) -> tuple[str, str]:
    values = dict(experiment)
    data = [_shown(k, values.get(k)) for k in differing if k == "dataset" or k.startswith("data.")]
    estimator = [_shown(k, values.get(k)) for k in differing if k.startswith("config.")]
    estimator += [_shown(k, values.get(k)) for k in differing if k == "revision"]
    dataset_label = record.dataset_label + (f" [{' '.join(data)}]" if data else "")
    estimator_label = record.estimator_label + (f" [{' '.join(estimator)}]" if estimator else "")
    return dataset_label, estimator_label


def split_experiments(records: list[RunRecord]) -> tuple[list[RunRecord], list[str]]:
    """``records`` relabelled so that one label pair holds one experiment, and one note
    per label pair that was split (module docstring). ``InputError`` naming both folders
    when one experiment holds the same seed twice. A failed run (its experiment unknown)
    keeps its labels and joins whichever row holds them."""
    by_labels: dict[tuple[str, str], dict[Experiment, list[RunRecord]]] = {}
    for record in records:
        pair = (record.dataset_label, record.estimator_label)
        by_labels.setdefault(pair, {}).setdefault(record.experiment, []).append(record)
    relabelled: dict[int, RunRecord] = {}
    notes = []
    for (dataset_label, estimator_label), experiments in by_labels.items():
        known = [experiment for experiment in experiments if experiment]
        differing: list[str] = []
        if len(known) > 1:
            keys = sorted({key for experiment in known for key, _ in experiment})
            differing = [key for key in keys if len({dict(e).get(key) for e in known}) > 1]
            shown = "; ".join(
                ", ".join(_shown(key, dict(experiment).get(key)) for key in differing)
                + f" ({len(experiments[experiment])} run{'s' * (len(experiments[experiment]) > 1)})"
                for experiment in known
            )
            notes.append(
                f"{dataset_label} / {estimator_label}: {len(known)} experiments, one row each "
                f"(they differ in {', '.join(_name(key) for key in differing)}): "
                f"{shown}"
            )
        for experiment, group in experiments.items():
            seen: dict[int, RunRecord] = {}
            for record in group:
                if record.seed in seen and experiment:
                    raise InputError(
                        f"{seen[record.seed].folder} and {record.folder} are the same run (seed "
                        f"{record.seed} of one experiment, {dataset_label} / {estimator_label}): "
                        "report one of them"
                    )
                seen[record.seed] = record
                if differing and experiment:
                    labels = _labels(record, experiment, differing)
                    relabelled[id(record)] = replace(
                        record, dataset_label=labels[0], estimator_label=labels[1]
                    )
    return [relabelled.get(id(record), record) for record in records], notes
