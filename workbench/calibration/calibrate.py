"""``workbench calibrate-noise``: fit a dataset's planar odometry noise model.

Against the truth when the dataset has it. Without truth, against the batch smoother's
estimate, iterated: fit, re-run the smoother with the fitted model, fit again (an EM-like
fixed point). A smoother's estimate follows the odometry it was given, so the first fit
against it is biased low; each iteration moves the model away from the stated noise and
the printed figures show whether it settled. Against a smoother the residuals include the
smoother's own relative error, which this does not subtract (it has no cross-covariances
of consecutive poses): the fit is then an upper bound on the odometry noise.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from datasets.errors import InputError
from datasets.odometry_calibration import (
    FitResult,
    Increments,
    build_windows,
    fit_odometry_noise,
    window_nees,
)
from datasets.odometry_noise import OdometryNoiseModel
from datasets.sequence import Sequence
from datasets.trajectory import Trajectory
from workbench.calibration.odometry_sources import planar_increments, truth_reference

SCALE_FACTORS = (0.25, 1.0, 4.0)
"""Window lengths (as multiples of ``window_s``) at which the fitted model is checked."""


@dataclass(frozen=True)
class Calibration:
    """A fitted model and the evidence for it.

    Attributes:
        fit: the final fit.
        reference: ``truth`` or ``smoother-batch (N iterations)``.
        window_s: the fitting window [s].
        nees_by_window: window length [s] -> (mean, median) NEES per dof of the fitted model
            on non-overlapping windows of that length (1 where the model holds at that scale;
            rising with the length: errors correlated in time).
        history: the fit of every iteration (smoother reference).
    """

    fit: FitResult
    reference: str
    window_s: float
    nees_by_window: dict[float, tuple[float, float]]
    history: tuple[FitResult, ...] = field(default=())

    def lines(self, dataset: str) -> list[str]:
        """What the command prints."""
        model = self.fit.model
        out = [
            f"{dataset}: odometry noise fitted against {self.reference} on {self.fit.windows} "
            f"windows of {self.window_s:g} s",
            *("  " + line for line in model.describe()),
        ]
        if len(self.fit.excluded):
            shown = ", ".join(f"{t:.1f}" for t in self.fit.excluded[:8])
            more = " ..." if len(self.fit.excluded) > 8 else ""
            out.append(
                f"  excluded {len(self.fit.excluded)} outlier window(s) (beyond the 99.99 % "
                f"chi-square quantile) starting at t = {shown}{more} s"
            )
        for length, (mean, median) in self.nees_by_window.items():
            out.append(
                f"  NEES per dof on {length:g} s windows: mean {mean:.3g}, median {median:.3g}"
            )
        for index, step in enumerate(self.history[:-1], start=1):
            out.append(f"  iteration {index}: NEES/dof {step.nees_per_dof:.3g}")
        return out

    def write(self, path: Path, dataset: str) -> None:
        """The model as YAML (``--data odometry_noise=PATH`` reads it back)."""
        document = {
            "dataset": dataset,
            "reference": self.reference,
            "window_s": self.window_s,
            "windows": self.fit.windows,
            "excluded_windows": len(self.fit.excluded),
            "nees_per_dof_by_window_s": {
                float(k): {"mean": float(v[0]), "median": float(v[1])}
                for k, v in self.nees_by_window.items()
            },
            "odometry_noise": self.fit.model.as_dict(),
        }
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        scratch = path.with_name(f".{path.name}.tmp")
        scratch.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
        scratch.replace(path)


def _check(
    model: OdometryNoiseModel, increments: Increments, reference: Trajectory, window_s: float
) -> dict[float, tuple[float, float]]:
    checks = {}
    for factor in SCALE_FACTORS:
        length = window_s * factor
        try:
            windows = build_windows(
                increments, reference.t, reference.positions, reference.rotations, length
            )
        except InputError:
            continue
        per_dof = window_nees(model.rates, windows) / 3.0
        checks[length] = (float(np.mean(per_dof)), float(np.median(per_dof)))
    return checks


def calibrate_against(
    increments: Increments,
    reference: Trajectory,
    window_s: float,
    source: str,
    free: np.ndarray | None = None,
) -> tuple[FitResult, dict[float, tuple[float, float]]]:
    """One fit against one reference, and its check at other window lengths."""
    windows = build_windows(
        increments, reference.t, reference.positions, reference.rotations, window_s
    )
    fit = fit_odometry_noise(windows, source, free)
    return fit, _check(fit.model, increments, reference, window_s)


def calibrate(
    dataset: str,
    load: Callable[[dict[str, str]], Sequence],
    reference: str = "auto",
    window_s: float = 5.0,
    iterations: int = 3,
    smoother: Callable[[Sequence], Trajectory] | None = None,
) -> Calibration:
    """Fit the odometry noise of ``dataset`` (module docstring).

    Args:
        dataset: its name (for messages).
        load: loads the dataset with extra ``--data`` options (the smoother iterations pass
            ``odometry_noise=FILE``).
        reference: ``truth``, ``smoother`` or ``auto`` (truth when there is one).
        window_s: fitting window [s].
        iterations: smoother iterations.
        smoother: runs the batch smoother on a sequence and returns its smoothed trajectory.
    """
    sequence = load({})
    increments = planar_increments(sequence)
    has_truth = sequence.ground_truth is not None and sequence.ground_truth.pose is not None
    if reference == "auto":
        reference = "truth" if has_truth else "smoother"
    if reference == "truth":
        fit, checks = calibrate_against(
            increments,
            truth_reference(sequence),
            window_s,
            f"fitted against the truth of {dataset}",
        )
        return Calibration(fit, "truth", window_s, checks)
    if reference != "smoother":
        raise InputError(
            f"calibrate-noise: --reference must be auto, truth or smoother, got '{reference}'"
        )
    if smoother is None:
        raise InputError("calibrate-noise: no smoother to fit against")
    if iterations < 1:
        raise InputError(f"calibrate-noise: --iterations must be >= 1, got {iterations}")
    history: list[FitResult] = []
    checks: dict[float, tuple[float, float]] = {}
    with tempfile.TemporaryDirectory(prefix="calibrate-noise-") as scratch:
        model_file = Path(scratch) / "odometry_noise.yaml"
        current = sequence
        for iteration in range(1, iterations + 1):
            trajectory = smoother(current)
            source = (
                f"fitted against the batch smoother on {dataset} "
                f"({iteration} iteration{'s' if iteration > 1 else ''})"
            )
            fit, checks = calibrate_against(increments, trajectory, window_s, source)
            history.append(fit)
            Calibration(fit, "smoother", window_s, checks).write(model_file, dataset)
            current = load({"odometry_noise": str(model_file)})
    label = f"smoother-batch ({iterations} iteration{'s' if iterations > 1 else ''})"
    return Calibration(history[-1], label, window_s, checks, tuple(history))
