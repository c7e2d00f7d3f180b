"""``workbench bag``'s estimators (steps 2 and 3 of ``workbench.commands.bag``): which run
(every registered one the bag's sensors allow, the others an n/a row with the reason), each
into its run folder, then the table and figures of them all."""

from __future__ import annotations

from pathlib import Path

import typer

from datasets.errors import InputError


def _status(text: str, limit: int = 160) -> str:
    """One table-safe line: no newlines or pipes, at most ``limit`` characters."""
    flat = " ".join(text.split()).replace("|", "/")
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def not_applicable(requested: list[str] | None, sequence) -> dict[str, str]:
    """Every registered estimator the sequence's sensors or dimension do not allow, with the
    reason (``workbench.runner.check_compatible``, as ``bench`` says it), when none were
    requested by name (a requested one that cannot run fails in its own row)."""
    from workbench.registry import ESTIMATORS
    from workbench.runner import check_compatible

    if requested:
        return {}
    reasons = {}
    for entry in ESTIMATORS:
        try:
            check_compatible(entry.name, entry.load(), sequence)
        except InputError as error:
            reasons[entry.name] = str(error)
    return reasons


def choose_estimators(requested: list[str] | None, sequence) -> list[str]:
    """The requested names (checked), or every registered estimator the sequence allows."""
    from workbench.registry import ESTIMATORS, estimator_entry
    from workbench.runner import is_compatible

    if requested:
        for name in requested:
            estimator_entry(name)  # InputError listing the known ones
        return list(dict.fromkeys(requested))
    return [entry.name for entry in ESTIMATORS if is_compatible(entry.load(), sequence)]


def run_estimators(
    sequence,
    out: Path,
    rows: list[dict],
    notes: list[str],
    names: list[str],
    skipped: dict[str, str],
    overrides: dict,
    data_options: tuple,
    plots: bool,
    quiet: bool,
    plot_formats: tuple[str, ...],
    disable: bool,
) -> list[dict]:
    """Each of ``names`` on ``sequence`` into ``out/<name>/``, then the table and figures
    of them, with an n/a row and its reason for each of ``skipped`` (``bench``'s rows);
    returns ``rows`` with a row per estimator run."""
    from workbench.reporting import write_report
    from workbench.results.runs import load_runs
    from workbench.results.summary import PlannedPair
    from workbench.run_folder import write_failed_run, write_run_folder
    from workbench.runner import RunRequest, execute

    for name in names:
        row = {"estimator": name, "status": "ok"}
        try:
            from workbench.progress import sequence_progress

            with sequence_progress(disable) as progress:
                start = sequence.initial_state.t if sequence.initial_state else 0.0
                task = progress.add_task(name, total=None)
                result = execute(
                    RunRequest(
                        estimator=name,
                        dataset=sequence.name,
                        overrides=tuple(overrides[name].items()),
                        data_options=data_options,
                    ),
                    sequence=sequence,
                    on_step=lambda t, task=task, start=start: progress.update(
                        task, completed=t - start
                    ),
                )
            write_run_folder(result, out / name, plot_formats if plots else ())
        except InputError as error:
            row["status"] = _status(f"not run: {error}")
            typer.echo(f"warning: {name}: {error}", err=True)
        except Exception as error:  # one estimator's failure must not lose the others' results
            row["status"] = _status(f"failed: {type(error).__name__}: {error}")
            typer.echo(f"warning: {name} failed: {row['status']}", err=True)
        if row["status"] != "ok":
            request = {"dataset": sequence.name, "estimator": name, "seed": 0}
            write_failed_run(out / name, request, row["status"])
        rows.append(row)
    folders = [out / name for name in names]
    records = load_runs(folders)
    # the estimators the bag's sensors do not allow: n/a rows with the reason, as bench's
    planned = [
        PlannedPair(record.dataset_label, record.estimator_label, record.estimator, 1)
        for record in records
    ] + [PlannedPair(sequence.name, name, name, 0, reason) for name, reason in skipped.items()]
    for name, reason in skipped.items():
        typer.echo(f"n/a: {name}: {reason}", err=True)
    # the comparison figures as bench draws them, in the formats asked for
    report = write_report(
        records, out, planned, notes=notes, plot_formats=plot_formats if plots else ()
    )
    if not quiet:
        from workbench.commands.bench import show_report

        show_report(report, "")  # the dataset is the bag: the tables are titled with it
    return rows
