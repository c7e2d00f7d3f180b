"""``workbench observability DATASET [--set anchors=N]``: rank of Aghili's eq. (22) along the
true trajectory, smallest singular value, and the collinear-anchor flag (eq. (27))."""

from __future__ import annotations

from typing import Annotated, Optional

import numpy as np
import typer

from datasets.errors import InputError
from datasets.options import parse_assignments


def register(app: typer.Typer) -> None:
    @app.command("observability")
    def observability_command(
        dataset: Annotated[str, typer.Argument(help="dataset name, e.g. sim:aghili-rover")],
        set_: Annotated[Optional[list[str]], typer.Option("--set", help="anchors=N, step_s=S, landmarks=K")] = None,
        seed: Annotated[int, typer.Option("--seed")] = 0,
    ) -> None:
        """Per-segment observability (Aghili eq. (22)) along the ground-truth trajectory."""
        from datasets.rotations import so3_log
        from filters.aghili.observability import observability_matrix, rank_report, segment_matrices
        from workbench.registry import load_dataset

        options = parse_assignments(set_ or [], "--set")
        unknown = set(options) - {"anchors", "step_s", "landmarks"}
        if unknown:
            raise InputError(f"observability --set: unknown keys {sorted(unknown)} (known: anchors, step_s, landmarks)")
        anchors_count = int(options.get("anchors", 3))
        step_s = float(options.get("step_s", 10.0))
        landmark_count = int(options.get("landmarks", 3))
        sequence = load_dataset(dataset, seed)
        truth = None if sequence.ground_truth is None else sequence.ground_truth.pose
        if truth is None or sequence.known_landmarks is None or len(sequence.known_landmarks) < anchors_count:
            raise InputError(f"{dataset}: observability needs a ground-truth trajectory and {anchors_count} known landmarks")
        anchors = sequence.known_landmarks.positions[:anchors_count]
        others = sequence.known_landmarks.positions[anchors_count:]
        rotations = truth.rotation_matrices()
        typer.echo(f"{'t [s]':>8} {'rank':>5} {'size':>5} {'min sv':>10} {'collinear':>9}")
        for index in np.searchsorted(truth.t, np.arange(truth.t[0], truth.t[-2], step_s)):
            dt = truth.t[index + 1] - truth.t[index]
            attitude, position = rotations[index], truth.positions[index]
            omega = so3_log(attitude.T @ rotations[index + 1]) / dt
            accel = np.zeros(3)
            if index + 2 < len(truth.t):
                accel = (truth.positions[index + 2] - 2 * truth.positions[index + 1] + position) / dt**2
            a_bar = attitude.T @ (accel + np.array([0.0, 0.0, 9.81]))
            nearest = others[np.argsort(np.linalg.norm(others - position, axis=1))[:landmark_count]]
            F, H = segment_matrices(attitude, position, omega, a_bar, anchors, nearest)
            result = rank_report(observability_matrix(F, H), F.shape[0], anchors_body=(anchors - position) @ attitude)
            collinear = "-" if result.anchors_collinear is None else str(result.anchors_collinear)
            typer.echo(f"{truth.t[index]:8.1f} {result.rank:5d} {result.size:5d} {result.smallest_singular_values[0]:10.3e} {collinear:>9}")
