"""A paper pack (``workbench report RUNS --paper DIR``): what a paper needs from a set of runs,
in one folder a LaTeX project can take as it is.

- ``tables/NAME.tex``: the chosen LaTeX tables (``results.latex``; every preset by default),
  and ``tables/table.csv`` (every column, the consistency bands the captions point to);
- ``figures/<dataset>/*.pdf``: each dataset's comparison figures
  (``report_plots.write_dataset_plots``);
- ``evaluation.tex``: the evaluation protocol as a paragraph to ``\\input`` (no preamble),
  stated from what was run: the estimators and their non-default options, the data (names,
  options, sources and their versions, references, calibrations), runs and seeds, the ATE
  alignment and RPE step as the runs' evo result files record them, the NEES and NIS
  definitions with the dof the runs had, the chi-square bands and the verdict rule with its
  false-alarm rates (``workbench.metrics.verdicts``), and the software versions and code
  revision of metrics.json. Nothing in it is typed in: every number comes from the runs or
  from the code's constants.

The folder follows the rules of every output (``workbench.owned_folders``): new, empty or an
earlier collection of the workbench's, locked while written. Files an earlier pack wrote
there and this one does not (a table not chosen, a dataset no longer in the runs) are
removed: a pack holds one set of runs.
"""

from __future__ import annotations

import json
import re
import zipfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from datasets.trajectory_io import write_atomic
from workbench.reporting import Report, ReportRows, report_rows
from workbench.results.columns import CUSTOM, DEFAULT_TABLE, PRESETS, parse_table_choice
from workbench.results.latex import latex_tables
from workbench.results.latex_captions import dof_phrase, verdict_rule_latex
from workbench.results.latex_text import latex_escape
from workbench.results.runs import RunRecord
from workbench.results.summary import PairSummary
from workbench.results.tables import csv_table
from workbench.suites import slug

EVALUATION_FILE = "evaluation.tex"
FIGURE_FORMAT = "pdf"


@dataclass(frozen=True)
class PaperPack:
    """What a pack wrote: its folder, every file (relative to it), and the report (rows,
    table files by key, figures folder, notes) for the terminal."""

    folder: Path
    files: list[Path]
    report: Report


def write_paper_pack(
    records: list[RunRecord],
    out: Path,
    table: str = DEFAULT_TABLE,
    figures: bool = True,
    seed: int | None = None,
    reference: str | None = None,
) -> PaperPack:
    """The pack of ``records`` into ``out`` (module docstring; the caller claims and locks
    ``out``). ``table``: ``results.columns.parse_table_choice``; ``figures``: False writes
    none; ``seed``: the run per-seed figures show; ``reference``: every ATE over this
    estimator's, per dataset."""
    from workbench.report_plots import write_dataset_plots

    out = Path(out)
    found = report_rows(records, notes=(), reference=reference)
    written: list[Path] = []
    tables_dir = out / "tables"
    tables_dir.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    prefix = slug(out.name).lower()
    for name, columns in parse_table_choice(table):
        text = latex_tables(found.rows, name, columns, f"tab:{prefix}-{name}")
        paths[f"tex:{name}"] = write_atomic(tables_dir / f"{name}.tex", text)
    for name in (*PRESETS, CUSTOM):
        if f"tex:{name}" not in paths:
            (tables_dir / f"{name}.tex").unlink(missing_ok=True)
    paths["csv"] = write_atomic(tables_dir / "table.csv", csv_table(found.rows))
    written += paths.values()
    figures_dir = out / "figures"
    folders = found.dataset_folders() if figures else {}
    _remove_stale_figures(figures_dir, {slug(dataset) for dataset in folders})
    for dataset, dataset_folders in folders.items():
        target = figures_dir / slug(dataset)
        written += write_dataset_plots(dataset_folders, dataset, target, (FIGURE_FORMAT,), seed)
    written.append(write_atomic(out / EVALUATION_FILE, evaluation_tex(found)))
    report = Report(found.rows, paths, figures_dir if folders else None, found.notes)
    return PaperPack(out, [path.relative_to(out) for path in written], report)


def _remove_stale_figures(figures_dir: Path, keep: set[str]) -> None:
    """Figures of datasets an earlier pack here had and this one has not: their PDFs (what
    a pack writes there), and the folder once empty."""
    if not figures_dir.is_dir():
        return
    for folder in figures_dir.iterdir():
        if folder.is_dir() and folder.name not in keep:
            for figure in folder.glob(f"*.{FIGURE_FORMAT}"):
                figure.unlink()
            if not any(folder.iterdir()):
                folder.rmdir()


# --------------------------------------------------------------------------- reading runs


def _config(record: RunRecord) -> dict[str, Any]:
    """A run folder's config.yaml (empty when it has none)."""
    from datasets.yaml_files import read_yaml_file

    path = record.folder / "config.yaml"
    found = read_yaml_file(path) if path.is_file() else {}
    return found if isinstance(found, dict) else {}


def _evo_title(record: RunRecord, name: str) -> str | None:
    """The ``info.json`` title of the run's evo result file ``name`` (``ape.zip``)."""
    path = record.folder / name
    if not path.is_file():
        return None
    try:
        with zipfile.ZipFile(path) as archive:
            return str(json.loads(archive.read("info.json")).get("title") or "") or None
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None


def _alignment(record: RunRecord) -> str | None:
    """The ATE's alignment as the run's ape.zip states it: ``SE(3) Umeyama``."""
    title = _evo_title(record, "ape.zip") or _evo_title(record, "ape_smoothed.zip")
    found = re.search(r"with (.+?) alignment", title or "")
    return found.group(1) if found else None


def _rpe_step(record: RunRecord) -> str | None:
    """The RPE's step as the run's rpe.zip states it: ``delta = 1 (frames) using
    consecutive pairs (not aligned)``."""
    title = _evo_title(record, "rpe.zip") or _evo_title(record, "rpe_smoothed.zip")
    found = re.search(r"(delta = .*)", (title or "").replace("\n", " "))
    return found.group(1).strip() if found else None


def _source_text(source: str, versions: dict[str, str]) -> str:
    """A data source as a reader can find it: a file inside an installed package as
    ``package/relative/path`` with the package's version; anything else as it is."""
    parts = Path(source).parts
    if "site-packages" in parts:
        inside = parts[parts.index("site-packages") + 1 :]
        if inside:
            package = inside[0]
            version = versions.get(package)
            shown = _path_latex("/".join(inside))
            return shown + (f" (the {latex_escape(package)} {version} wheel)" if version else "")
    return _path_latex(source)


def _path_latex(path: str) -> str:
    """A path in typewriter type that may break after each ``/`` (a long one would
    overflow the line)."""
    return "\\texttt{" + "/\\allowbreak{}".join(latex_escape(p) for p in path.split("/")) + "}"


def _seeds_text(seeds: list[int]) -> str:
    seeds = sorted(set(seeds))
    if len(seeds) > 2 and seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"seeds {seeds[0]}--{seeds[-1]}"
    return ("seed " if len(seeds) == 1 else "seeds ") + ", ".join(map(str, seeds))


def _options_text(options: Any) -> str:
    if not isinstance(options, dict) or not options:
        return ""
    return ", ".join(
        f"\\texttt{{{latex_escape(str(key))}={latex_escape(str(value))}}}"
        for key, value in options.items()
    )


def _non_default_options(estimator: str, config: Any) -> dict[str, Any]:
    """The options of a run's resolved estimator config that differ from the estimator's
    defaults (the registry's ``Config``); {} when it cannot be compared."""
    from datasets.errors import InputError
    from datasets.option_renames import renamed_options
    from workbench.registry import estimator_entry

    if not isinstance(config, dict):
        return {}
    try:
        defaults = estimator_entry(estimator).load().Config().model_dump(mode="json")
    except Exception:  # an estimator no longer registered: its options stay in config.yaml
        return {}
    # a run written before issue 39 recorded some options under their old names
    try:
        config, _ = renamed_options(config, defaults, estimator)
    except InputError:  # an old and a new name disagreeing: shown as recorded
        pass
    return {key: value for key, value in config.items() if defaults.get(key) != value}


# --------------------------------------------------------------------------- the text


def _data_sentence(dataset: str, rows: list[PairSummary], versions: dict[str, str]) -> str:
    runs = [run for row in rows for run in row.finished_runs]
    first = runs[0]
    config = _config(first)
    metadata = config.get("dataset_metadata")
    metadata = metadata if isinstance(metadata, dict) else {}
    name = str(config.get("dataset") or first.dataset)
    parts = [f"\\emph{{{latex_escape(dataset)}}}:"]
    described = [] if name == dataset else [f"\\texttt{{{latex_escape(name)}}}"]
    source = metadata.get("source")
    if source == "simulator":
        scenario = metadata.get("scenario")
        described.append(
            "the workbench's simulator"
            + (f" (scenario \\texttt{{{latex_escape(str(scenario))}}})" if scenario else "")
        )
    elif source:
        described.append(_source_text(str(source), versions))
    options = _options_text(config.get("data_options"))
    if options:
        described.append(f"options {options}")
    parts.append(", ".join(described) + ";" if described else "")
    per_row = Counter(len(row.finished_runs) for row in rows)
    counts = " or ".join(str(count) for count in sorted(per_row))
    seeds = [run.seed for run in runs]
    parts.append(f"{counts} run{'s' * (max(per_row) > 1)} per estimator ({_seeds_text(seeds)});")
    references = sorted(
        {str((run.metrics or {}).get("reference_source")) for run in runs} - {"None", ""}
    )
    held_out, used = (metadata.get(key) for key in ("gps_fixes_held_out", "gps_fixes_used"))
    if references and isinstance(held_out, int) and isinstance(used, int):
        # a loader that holds fixes out says how many (kitti-imu-gps: a seeded fraction)
        references[-1] += f" ({held_out} of {held_out + used} fixes)"
    parts.append(
        "reference: " + ", ".join(latex_escape(text) for text in references)
        if references
        else "no reference (no accuracy or NEES figure)"
    )
    calibrations = sorted({text for row in rows for text in row.calibrations()})
    if calibrations:
        parts[-1] += "; models fitted on " + "; ".join(latex_escape(c) for c in calibrations)
    excluded = [float((run.metrics or {}).get("excluded_truth_s") or 0.0) for run in runs]
    if any(excluded):
        parts[-1] += (
            f"; truth scored nowhere (untrusted intervals): {max(excluded):.3g}\\,s at most "
            "in a run"
        )
    alignments = sorted({a for run in runs if (a := _alignment(run))})
    if alignments:
        parts[-1] += "; ATE aligned by " + " and ".join(latex_escape(a) for a in alignments)
    return " ".join(part for part in parts if part) + "."


def _estimator_sentence(rows: list[PairSummary]) -> str:
    from workbench.registry import ESTIMATORS

    order = [entry.name for entry in ESTIMATORS]
    labels: dict[str, list[RunRecord]] = {}
    for row in rows:
        labels.setdefault(row.estimator, []).extend(row.finished_runs)
    shown = []

    def registry_order(item: tuple[str, list[RunRecord]]) -> int:
        name = item[1][0].estimator if item[1] else ""
        return order.index(name) if name in order else len(order)

    for label, runs in sorted(labels.items(), key=registry_order):
        if not runs:
            continue
        changed = _non_default_options(runs[0].estimator, _config(runs[0]).get("config"))
        text = f"\\texttt{{{latex_escape(label)}}}"
        if changed:
            text += " (" + _options_text(changed) + ")"
        shown.append(text)
    return (
        f"Estimators ({len(shown)}): "
        + ", ".join(shown)
        + "; in parentheses the resolved options that differ from the estimator's defaults "
        "(every run's are in its config.yaml)."
    )


def _software_sentence(runs: list[RunRecord]) -> str:
    versions: dict[str, Counter] = {}
    revisions: Counter = Counter()
    for run in runs:
        metrics = run.metrics or {}
        for package, version in (metrics.get("package_versions") or {}).items():
            versions.setdefault(str(package), Counter())[str(version)] += 1
        revisions[str(metrics.get("git_revision") or "unknown")] += 1
    packages = []
    for package, found in sorted(versions.items()):
        if len(found) == 1:
            packages.append(f"{latex_escape(package)}~{next(iter(found))}")
        else:
            each = ", ".join(f"{v} ({n} runs)" for v, n in sorted(found.items()))
            packages.append(f"{latex_escape(package)} {each}")
    texts = []
    for revision, count in revisions.most_common():
        dirty = revision.endswith("+dirty")
        text = f"\\texttt{{{latex_escape(revision.removesuffix('+dirty'))}}}"
        if dirty:
            text += " with uncommitted changes"
        if len(revisions) > 1:
            text += f" ({count} runs)"
        texts.append(text)
    return (
        "Software (the runs' metrics.json): "
        + ", ".join(packages)
        + "; code revision "
        + "; ".join(texts)
        + "."
    )


def _versions(runs: list[RunRecord]) -> dict[str, str]:
    """The package versions the runs record (the first run's, as data sources cite one)."""
    for run in runs:
        found = (run.metrics or {}).get("package_versions")
        if isinstance(found, dict):
            return {str(k): str(v) for k, v in found.items()}
    return {}


def evaluation_tex(found: ReportRows) -> str:
    """The evaluation protocol of the runs behind ``found`` (module docstring)."""
    from workbench.metrics.consistency import CONFIDENCE
    from workbench.metrics.timestamps import DEFAULT_MAX_DIFF_S

    rows = [row for row in found.rows if row.finished_runs]
    runs = [run for row in rows for run in row.finished_runs]
    versions = _versions(runs)
    datasets = list(dict.fromkeys(row.dataset for row in rows))
    steps = sorted({step for run in runs if (step := _rpe_step(run))})
    has_holdout = any(
        "gps_holdout_rmse_m" in r.stats or "gps_holdout_rmse_smoothed_m" in r.stats for r in rows
    )
    cells = [column for _, columns in parse_table_choice(DEFAULT_TABLE) for column in columns]
    consistency = tuple(column for column in cells if column.kind == "cell")
    dofs = dof_phrase(rows, consistency)
    lines = [
        "% Evaluation protocol, written by `workbench report --paper` from the run folders",
        "% (metrics.json, config.yaml, the evo result files ape.zip and rpe.zip) and the",
        "% workbench's constants: \\input{evaluation} where it belongs (no package needed).",
        "\\begin{sloppypar}",
        "\\noindent\\textbf{Evaluation protocol.}",
        _estimator_sentence(rows),
        f"Each ran on each of {len(datasets)} dataset{'s' * (len(datasets) > 1)} "
        "whose sensors it needs.",
    ]
    for dataset in datasets:
        lines.append(_data_sentence(dataset, [r for r in rows if r.dataset == dataset], versions))
    lines.append(
        "Accuracy: the ATE is the RMSE of the position error after aligning the estimate to "
        "the reference (the alignment of each dataset above), poses paired with the "
        f"reference by the nearest time stamp within {DEFAULT_MAX_DIFF_S:g}\\,s; the RPE is the "
        "RMSE of the relative pose error"
        + (
            " with " + "; ".join(latex_escape(step) for step in steps)
            if steps
            else " between consecutive poses"
        )
        + ", translation and rotation; both as evo computes them (each run's ape.zip and "
        "rpe.zip are evo result files)."
        + (
            " The GPS hold-out error is the RMSE of the estimated positions, interpolated at "
            "the time stamps of GPS fixes withheld from the estimators, without alignment."
            if has_holdout
            else ""
        )
    )
    lines.append(
        "Consistency: the NEES of a state block at a step is $e^\\top P^{-1} e$, $e$ the "
        "error of the estimate against the truth in the estimate's tangent space (a 3-D "
        "pose: rotation then translation, body-frame right perturbation; a planar pose: "
        "$x$, $y$, $\\theta$) and $P$ its covariance; the NIS of an update is "
        "$\\nu^\\top S^{-1} \\nu$, $\\nu$ the stacked innovation against the prediction "
        "before it and $S$ its covariance. Per degree of freedom: a run's values summed "
        "over its steps over their summed dof, averaged over the runs (1 is consistent)."
        + (f" Dof per step in these runs: {dofs}." if dofs else "")
        + " "
        + verdict_rule_latex()
        + ". The figures show the per-step average over runs with the two-sided "
        f"{CONFIDENCE * 100:g}\\,\\% chi-square band of its summed dof."
    )
    lines.append(
        "Tables: the mean over runs with its sample standard deviation rounded to two "
        "significant digits, in parentheses in units of the mean's last digit; the best "
        "value of each column and dataset in bold."
    )
    lines.append(_software_sentence(runs))
    lines.append("\\end{sloppypar}")
    return "\n".join(lines) + "\n"
