"""The comparison figures a reviewer accepts as they are (issue 36): the overlay holds the
reference and every estimator that ran, aligned as the ATE is (the errors drawn have the
table's ATE as RMSE); every log axis has at least two labelled ticks; no axis carries an
offset text, even on a bag's epoch stamps; no axes is empty; a front end's trajectory
beside bag run folders is drawn. Default tier: four short runs; the quick suite's figures:
a study."""

from __future__ import annotations

import shutil
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
import yaml
from matplotlib.collections import Collection
from matplotlib.figure import Figure
from matplotlib.image import AxesImage

from workbench.figures.common import TimeAxis
from workbench.figures.view import DatasetView
from workbench.report_plots import dataset_figures
from workbench.results.runs import read_run
from workbench.results.summary import summarize

EPOCH_S = 1.7e9
SHORT = {"duration_s": 3}
ESTIMATORS = ("dead-reckoning", "ekf-slam", "sensor-based", "smoother-batch")
"""A filter with a covariance, one without (the sensor-based filter's derived pose on this
scenario), the lower bound, and the batch smoother (no causal estimate)."""


# ---------------------------------------------------------------------------- checks


def _has_data(axes) -> bool:
    for line in axes.get_lines():
        x, y = (np.asarray(values, dtype=float) for values in line.get_data())
        if x.size and np.any(np.isfinite(x) & np.isfinite(y)):
            return True
    for collection in axes.collections:
        if isinstance(collection, Collection) and (
            len(collection.get_paths()) or len(collection.get_offsets())
        ):
            return True
    return any(isinstance(image, AxesImage) for image in axes.images)


def _labelled_ticks_in_view(axis) -> list[str]:
    low, high = sorted(axis.get_view_interval())
    locs = [loc for loc in axis.get_majorticklocs() if low <= loc <= high]
    labels = axis.get_major_formatter().format_ticks(locs)
    return [label for label in labels if label.strip()]


def _legend_texts(axes) -> list[str]:
    legend = axes.get_legend()
    return [] if legend is None else [text.get_text() for text in legend.get_texts()]


def check_figure(name: str, figure: Figure) -> None:
    """No empty axes, no offset text on any axis, two labelled ticks on every log axis."""
    figure.canvas.draw()
    assert figure.axes, name
    for axes in figure.axes:
        where = f"{name}: {axes.get_title() or axes.get_ylabel()}"
        assert _has_data(axes), f"empty axes in {where}"
        for axis in (axes.xaxis, axes.yaxis):
            assert axis.get_offset_text().get_text() == "", f"offset text in {where}"
        if axes.get_yscale() == "log":
            assert len(_labelled_ticks_in_view(axes.yaxis)) >= 2, f"log axis of {where}"


def check_overlay(figures: dict[str, Figure], pairs, has_reference: bool) -> None:
    """The trajectories figure holds the reference (where there is one) and every estimator
    that ran, each a drawn line (not a legend entry alone)."""
    (axes,) = figures["trajectories"].axes
    drawn = {
        line.get_label()
        for line in axes.get_lines()
        if len(line.get_xdata()) and np.any(np.isfinite(np.asarray(line.get_xdata(), float)))
    }
    assert any(label.startswith("reference") for label in drawn) == has_reference, drawn
    for pair in pairs:
        assert any(
            label == pair.estimator or label.startswith(f"{pair.estimator} smoothed")
            for label in drawn
        ), (pair.estimator, drawn)


def _draw_all(pairs, title: str) -> dict[str, Figure]:
    return dict(dataset_figures(pairs, title))


# ---------------------------------------------------------------------------- default tier


@pytest.fixture(scope="module")
def short_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four 3-second runs of sim:aghili-rover, one seed, as ``workbench run`` writes them."""
    from workbench import run

    root = tmp_path_factory.mktemp("figures") / "runs"
    for estimator in ESTIMATORS:
        run(estimator, "sim:aghili-rover", seed=1, data=SHORT, out=root / estimator)
    return root


def _pairs(folders: list[Path]):
    return summarize([read_run(folder) for folder in folders])


def test_overlay_errors_and_consistency_follow_the_rules(short_runs: Path) -> None:
    folders = sorted(short_runs.iterdir())
    pairs = _pairs(folders)
    with plt.rc_context({"figure.max_open_warning": 0}):
        figures = _draw_all(pairs, "sim:aghili-rover")
        try:
            assert {"trajectories", "position_error", "pose_errors", "consistency", "nis"} <= set(
                figures
            )
            for name, figure in figures.items():
                check_figure(name, figure)
            check_overlay(figures, pairs, has_reference=True)
            # no empty row: the estimators without causal pose sigmas are named in the legend
            pose_errors = figures["pose_errors"]
            rows = {axes.get_ylabel().split("\n")[0] for axes in pose_errors.axes}
            assert rows == {"dead-reckoning", "ekf-slam"}
            said = [text.get_text() for legend in pose_errors.legends for text in legend.texts]
            assert "sensor-based (no covariance)" in said
            assert "smoother-batch (no causal estimate)" in said
            pose_nees = next(
                axes
                for axes in figures["consistency"].axes
                if axes.get_ylabel() == "pose NEES / dof"
            )
            legend = _legend_texts(pose_nees)
            assert "sensor-based (no covariance)" in legend
            # one band for the estimators sharing the pose's 6 dof, labelled with it
            assert [text for text in legend if "band" in text] == ["95 % band, 6 dof"]
            assert any(text.startswith("smoother-batch smoothed (no causal") for text in legend)
        finally:
            plt.close("all")


def test_the_errors_drawn_are_the_tables_ate(short_runs: Path) -> None:
    pairs = _pairs(sorted(short_runs.iterdir()))
    view = DatasetView(pairs, "sim:aghili-rover")
    by_estimator = {path.estimator: path for path in view.paths}
    assert set(by_estimator) == set(ESTIMATORS)
    for pair, run in view.chosen:
        path = by_estimator[pair.estimator]
        key = "ate_rmse_m" if path.kind == "causal" else "ate_rmse_smoothed_m"
        assert path.kind == ("smoothed" if pair.estimator == "smoother-batch" else "causal")
        assert path.rmse == pytest.approx(run.metrics[key], rel=1e-6), pair.estimator
        assert path.align == "se3" and len(path.errors) == len(path.error_t)


def _shift_times(source: Path, target: Path, offset: float) -> None:
    """A copy of a run folder whose every stamp is ``offset`` seconds later (a bag's epoch
    clock): estimate.npz's ``*_t`` arrays, consistency.npz's ``*:t``, reference.tum."""
    shutil.copytree(source, target)
    for name, later in (("estimate.npz", "_t"), ("consistency.npz", ":t")):
        with np.load(source / name) as data:
            arrays = {key: data[key] for key in data.files}
        for key, values in arrays.items():
            if key.endswith(later) and np.issubdtype(values.dtype, np.floating):
                arrays[key] = values + offset
        np.savez_compressed(target / name, **arrays)
    reference = np.loadtxt(source / "reference.tum", comments="#", ndmin=2)
    reference[:, 0] += offset
    np.savetxt(target / "reference.tum", reference, fmt="%.9f")


def test_epoch_stamps_read_relative_to_t0_stated_once(short_runs: Path, tmp_path: Path) -> None:
    folders = []
    for source in sorted(short_runs.iterdir()):
        _shift_times(source, tmp_path / source.name, EPOCH_S)
        folders.append(tmp_path / source.name)
    pairs = _pairs(folders)
    with plt.rc_context({"figure.max_open_warning": 0}):
        figures = _draw_all(pairs, "epoch")
        try:
            timed = 0
            for name, figure in figures.items():
                check_figure(name, figure)
                stated = [text.get_text() for text in figure.texts] + [
                    axes.get_title() for axes in figure.axes
                ]
                time_axes = [axes for axes in figure.axes if axes.get_xlabel() == "t - t0 [s]"]
                if not time_axes:
                    continue
                timed += 1
                assert sum("t0 = 1700000000.000 s" in text for text in stated) == 1, name
                for axes in time_axes:
                    low, high = axes.get_xlim()
                    assert -1.0 < low and high < 10.0, (name, low, high)  # 3 s of data
            assert timed >= 5
        finally:
            plt.close("all")
    assert TimeAxis(0.0).label == "t [s]" and TimeAxis(0.0).note == ""


def test_the_front_end_beside_bag_runs_is_drawn(short_runs: Path, tmp_path: Path) -> None:
    """``workbench bag`` writes ``DIR/frontend/kiss_icp.tum`` beside ``DIR/NAME/`` run
    folders: the overlay and the error figure draw it, aligned as an estimator would be."""
    bag = tmp_path / "bag"
    for name in ("dead-reckoning", "ekf-slam"):
        shutil.copytree(short_runs / name, bag / name)
    reference = np.loadtxt(bag / "ekf-slam" / "reference.tum", comments="#", ndmin=2)
    drifting = reference.copy()
    drifting[:, 1] += 0.02 * (reference[:, 0] - reference[0, 0])  # 2 cm/s of drift
    (bag / "frontend").mkdir()
    np.savetxt(bag / "frontend" / "kiss_icp.tum", drifting, fmt="%.9f")
    pairs = _pairs([bag / "dead-reckoning", bag / "ekf-slam"])
    with plt.rc_context({"figure.max_open_warning": 0}):
        figures = _draw_all(pairs, "bag")
        try:
            check_overlay(figures, pairs, has_reference=True)
            for name in ("trajectories", "position_error"):
                (axes,) = [axes for axes in figures[name].axes if axes.get_lines()]
                labels = [line.get_label() for line in axes.get_lines()]
                assert any(label.startswith("kiss-icp (front end)") for label in labels), name
        finally:
            plt.close("all")


def test_a_run_folders_own_figures_follow_the_rules(monkeypatch, tmp_path: Path) -> None:
    import workbench.plots as plots
    from workbench import run

    captured: list[tuple[str, Figure]] = []

    def keep(figure: Figure, path: Path, formats: tuple[str, ...]) -> list[Path]:
        captured.append((path.name, figure))
        return []

    monkeypatch.setattr(plots, "save_figure", keep)
    result = run("ekf-slam", "sim:aghili-rover", seed=1, data=SHORT)
    plots.write_run_plots(result.estimate, result.sequence, tmp_path, "ekf-slam")
    try:
        names = {name for name, _ in captured}
        assert {"trajectory", "velocity", "nis", "landmark_count"} <= names, names
        for name, figure in captured:
            check_figure(name, figure)
    finally:
        plt.close("all")


# ---------------------------------------------------------------------------- study


SHORTER = {"duration_s": 4, "max_steps": 150}


@pytest.mark.study
def test_the_quick_suites_figures_follow_the_rules(tmp_path: Path) -> None:
    """The quick suite as a user would shorten it (its own YAML, durations cut), one run."""
    from workbench.cli import main
    from workbench.suite_files import suite_path

    suite_file = tmp_path / "quick-short.yaml"
    values = yaml.safe_load(suite_path("quick").read_text())
    for dataset in values["datasets"]:
        data = dataset.get("data", {})
        for key, value in SHORTER.items():
            if key in data:
                data[key] = min(value, data[key])
        if dataset["name"] == "kitti-imu-gps":
            data["duration_s"] = 10
    suite_file.write_text(yaml.safe_dump(values))
    out = tmp_path / "bench"
    assert main(["bench", str(suite_file), "--runs", "1", "--out", str(out), "--no-plots"]) == 0
    with plt.rc_context({"figure.max_open_warning": 0}):
        for dataset in sorted((out / "runs").iterdir()):
            folders = sorted(p.parent for p in dataset.glob("*/seed-*/metrics.json"))
            pairs = _pairs(folders)
            figures = _draw_all(pairs, dataset.name)
            try:
                for name, figure in figures.items():
                    check_figure(f"{dataset.name}/{name}", figure)
                has_reference = any((folder / "reference.tum").is_file() for folder in folders)
                check_overlay(figures, [p for p in pairs if p.finished_runs], has_reference)
                if has_reference:
                    assert "position_error" in figures and "pose_errors" in figures
            finally:
                plt.close("all")
