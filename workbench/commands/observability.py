"""``workbench observability DATASET [--set anchors=N]``: Aghili's observability analysis
along the true trajectory: per-segment rank of eq. (22) with its smallest singular value and
the Pi test of eqs. (25)-(27) (smallest singular value of Pi, collinear-anchor flag), and the total (eq. (30)) and stripped (eq. (32))
matrices over the last few segments."""

from __future__ import annotations

from typing import Annotated

import typer

from datasets.errors import InputError
from datasets.options import parse_assignments

KEYS = ("anchors", "step_s", "landmarks", "window")


def register(app: typer.Typer) -> None:
    @app.command("observability")
    def observability_command(
        dataset: Annotated[str, typer.Argument(help="dataset name, e.g. sim:aghili-rover")],
        set_: Annotated[
            list[str] | None,
            typer.Option(
                "--set", help="anchors=N (3), step_s=S (10), landmarks=K (3), window=W segments (3)"
            ),
        ] = None,
        seed: Annotated[int, typer.Option("--seed", help="dataset seed", min=0)] = 0,
    ) -> None:
        """Aghili eqs. (22), (27), (30), (32) along the ground-truth trajectory."""
        from filters.aghili.observability import observability_along_trajectory
        from workbench.registry import load_dataset

        options = parse_assignments(set_ or [], "--set")
        unknown = set(options) - set(KEYS)
        if unknown:
            raise InputError(
                f"observability --set: unknown keys {sorted(unknown)} (known: {', '.join(KEYS)})"
            )

        def number(key: str, default: float, kind: type) -> float:
            text = options.get(key)
            if text is None:
                return kind(default)
            try:
                return kind(text)
            except ValueError:
                raise InputError(
                    f"observability --set {key}={text}: expected {'an integer' if kind is int else 'a number'}"
                ) from None

        anchors_count = number("anchors", 3, int)
        step_s = number("step_s", 10.0, float)
        landmark_count = number("landmarks", 3, int)
        window = number("window", 3, int)
        if anchors_count < 1 or step_s <= 0 or landmark_count < 0 or window < 1:
            raise InputError(
                "observability --set: need anchors >= 1, step_s > 0, landmarks >= 0, window >= 1"
            )
        sequence = load_dataset(dataset, seed)
        truth = None if sequence.ground_truth is None else sequence.ground_truth.pose
        if truth is None or sequence.dimension != 3:
            raise InputError(f"{dataset}: observability needs a 3-D ground-truth trajectory")
        if sequence.known_landmarks is None or len(sequence.known_landmarks) < anchors_count:
            raise InputError(f"{dataset}: observability needs {anchors_count} known landmarks")
        anchors = sequence.known_landmarks.positions[:anchors_count]
        others = sequence.known_landmarks.positions[anchors_count:]
        reports = observability_along_trajectory(
            truth.t,
            truth.rotation_matrices(),
            truth.positions,
            anchors,
            others,
            step_s,
            landmark_count,
            window,
        )
        typer.echo(
            f"anchors={anchors_count}, landmarks={landmark_count}, state size {reports[0].segment.size}; "
            f"total/stripped over the last {window} segments of {step_s:g} s"
        )
        typer.echo(
            f"{'t [s]':>8} {'rank':>5} {'min sv':>10} {'Pi min sv':>10} {'collinear':>9} "
            f"{'total':>6} {'min sv':>10} {'stripped':>8} {'min sv':>10}"
        )
        for report in reports:
            segment = report.segment
            collinear = "-" if segment.anchors_collinear is None else str(segment.anchors_collinear)
            pi_sv = (
                "-"
                if segment.pi_smallest_singular_value is None
                else f"{segment.pi_smallest_singular_value:.3e}"
            )
            total, total_sv = _rank_cells(report.total)
            stripped, stripped_sv = _rank_cells(report.stripped)
            typer.echo(
                f"{report.t:8.1f} {segment.rank:5d} {segment.smallest_singular_values[0]:10.3e} {pi_sv:>10} {collinear:>9} "
                f"{total:>6} {total_sv:>10} {stripped:>8} {stripped_sv:>10}"
            )


def _rank_cells(report) -> tuple[str, str]:
    """(rank, smallest singular value) as table cells, "-" where no report exists yet."""
    if report is None:
        return "-", "-"
    return str(report.rank), f"{report.smallest_singular_values[0]:.3e}"
