"""One dataset's runs as the figures see them: the chosen seed's run of each estimator, its
arrays, the aligned trajectories and the one time axis, each computed once and shared by
every figure of the dataset."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from workbench.figures.aligned import (
    FRONT_END_LABEL,
    AlignedPath,
    align_as_ate,
    excluded_intervals,
    front_end_file,
    read_positions_file,
    reference_for_drawing,
    run_pose,
)
from workbench.figures.common import RunFiles, TimeAxis, curve_label
from workbench.results.runs import RunRecord
from workbench.results.summary import PairSummary


def chosen_run(pair: PairSummary, seed: int | None) -> RunRecord | None:
    """The finished run with ``seed`` (None: the lowest seed), or None."""
    runs = pair.finished_runs
    if seed is None:
        return runs[0] if runs else None
    return next((run for run in runs if run.seed == seed), None)


def seed_text(seed: int | None) -> str:
    return "first seed" if seed is None else f"seed {seed}"


@dataclass(frozen=True)
class Unaligned:
    """An estimator drawn as it was estimated (no reference to align it to)."""

    label: str
    estimator: str
    kind: str
    positions: np.ndarray


class DatasetView:
    """The figures' view of one dataset: ``pairs`` with finished runs, the ``seed`` the
    per-run figures show (None: each pair's lowest)."""

    def __init__(self, pairs: list[PairSummary], title: str, seed: int | None = None) -> None:
        self.pairs = [pair for pair in pairs if pair.finished_runs]
        self.title = title
        self.seed = seed
        self._files: dict[str, RunFiles] = {}

    def run(self, pair: PairSummary) -> RunRecord | None:
        return chosen_run(pair, self.seed)

    def files(self, run: RunRecord) -> RunFiles:
        key = str(run.folder)
        if key not in self._files:
            self._files[key] = RunFiles(run.folder)
        return self._files[key]

    @cached_property
    def chosen(self) -> list[tuple[PairSummary, RunRecord]]:
        """(pair, its run of the seed) for every pair that has one, in table order."""
        found = [(pair, self.run(pair)) for pair in self.pairs]
        return [(pair, run) for pair, run in found if run is not None]

    @cached_property
    def seed_label(self) -> str:
        seeds = sorted({run.seed for _, run in self.chosen})
        if len(seeds) == 1:
            return f"seed {seeds[0]}"
        return seed_text(self.seed) if self.seed is not None else "first seed of each"

    # ------------------------------------------------------------------ reference

    @cached_property
    def _reference(self):
        """(reference trajectory, its excluded intervals, reference label) of the chosen
        seed, or Nones: the first run that has one (every run of a seed shares it)."""
        for _, run in self.chosen:
            reference = read_positions_file(run.folder / "reference.tum")
            if reference is not None:
                metrics = run.metrics or {}
                source = metrics.get("reference_source")
                label = f"reference ({source})" if source else "reference"
                return reference, excluded_intervals(metrics), label
        return None, (), None

    @property
    def reference_label(self) -> str | None:
        return self._reference[2]

    @cached_property
    def reference_positions(self) -> np.ndarray | None:
        reference, excluded, _ = self._reference
        return None if reference is None else reference_for_drawing(reference, excluded)

    # ------------------------------------------------------------------ trajectories

    def scored_kind(self, run: RunRecord) -> str | None:
        """``causal`` when the run has a causal pose, else ``smoothed`` (the batch smoother),
        else None: what its ATE scores and what the figures draw."""
        files = self.files(run)
        for kind in ("causal", "smoothed"):
            if files.has_pose(kind):
                return kind
        return None

    @cached_property
    def paths(self) -> list[AlignedPath]:
        """Every estimator's scored trajectory aligned as its ATE is (those the ATE can
        score), then the front end's; empty without a reference."""
        reference, excluded, _ = self._reference
        if reference is None:
            return []
        found = []
        for pair, run in self.chosen:
            kind = self.scored_kind(run)
            pose = None if kind is None else run_pose(self.files(run), kind)
            if pose is None:
                continue
            label = curve_label(pair.estimator, kind, has_causal=kind == "causal")
            path = align_as_ate(reference, pose, excluded, label, pair.estimator, kind)
            if path is not None:
                found.append(path)
        for front in self.front_ends:
            path = align_as_ate(reference, front, excluded, FRONT_END_LABEL, "", "front end")
            if path is not None:
                found.append(path)
        return found

    @cached_property
    def unaligned(self) -> list[Unaligned]:
        """Every estimator's scored trajectory as estimated (for a dataset without a
        reference), then the front end's."""
        found = []
        for pair, run in self.chosen:
            kind = self.scored_kind(run)
            pose = None if kind is None else run_pose(self.files(run), kind)
            if pose is not None:
                label = curve_label(pair.estimator, kind, has_causal=kind == "causal")
                found.append(Unaligned(label, pair.estimator, kind, _spatial(pose.positions)))
        for front in self.front_ends:
            found.append(Unaligned(FRONT_END_LABEL, "", "front end", front.positions))
        return found

    @cached_property
    def front_ends(self) -> list:
        """The front end's own trajectory beside the chosen runs (a bag's KISS-ICP), once."""
        files = {front_end_file(run.folder) for _, run in self.chosen} - {None}
        found = [read_positions_file(path) for path in sorted(files)]
        return [trajectory for trajectory in found if trajectory is not None][:1]

    def not_drawn(self, drawn: set[str]) -> list[tuple[PairSummary, str]]:
        """(pair, why) for every pair whose trajectory is not among ``drawn`` estimators."""
        found = []
        for pair in self.pairs:
            if pair.estimator in drawn:
                continue
            run = self.run(pair)
            if run is None:
                found.append((pair, f"no finished run of {seed_text(self.seed)}"))
            elif self.scored_kind(run) is None:
                found.append((pair, "no world trajectory"))
            else:
                found.append((pair, "no pose paired with the reference"))
        return found

    # ------------------------------------------------------------------ time

    @cached_property
    def time_axis(self) -> TimeAxis:
        """t0: the earliest pose of the chosen runs or of the reference."""
        starts = []
        reference = self._reference[0]
        if reference is not None and len(reference):
            starts.append(float(reference.t[0]))
        for _, run in self.chosen:
            files = self.files(run)
            for key in ("pose_t", "smoothed_pose_t"):
                (t,) = files.arrays(key)
                if len(t):
                    starts.append(float(t[0]))
        return TimeAxis.starting_at(starts)


def _spatial(positions: np.ndarray) -> np.ndarray:
    if positions.shape[1] == 3:
        return positions
    return np.column_stack([positions, np.zeros(len(positions))])
