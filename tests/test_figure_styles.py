"""Every figure of the quick suite (shortened) draws each estimator in its one colour, in
every axes of every figure of every dataset; causal solid, smoothed dashed; no estimator
that ran is left out of a per-estimator figure."""

from __future__ import annotations

import matplotlib.colors as mcolors
import matplotlib.pyplot as plt
import pytest
import yaml

from workbench.cli import main
from workbench.registry import ESTIMATORS
from workbench.report_plots import dataset_figures
from workbench.results.runs import read_run
from workbench.results.summary import summarize
from workbench.style import estimator_style
from workbench.suite_files import suite_path

# a study: the second tier (`pytest -m study`): it runs the quick suite, shortened
pytestmark = pytest.mark.study

NAMES = sorted((entry.name for entry in ESTIMATORS), key=len, reverse=True)
SHORTER = {"duration_s": 4, "max_steps": 150}


def _estimator_in(text: str) -> str | None:
    """The registered estimator a label, title or axis label starts with."""
    for name in NAMES:
        if text == name or text.startswith((f"{name} ", f"{name}:", f"{name}\n")):
            return name
    return None


@pytest.fixture(scope="module")
def quick_figures(tmp_path_factory: pytest.TempPathFactory):
    """The quick suite as a user would shorten it (its own YAML, durations cut), 2 runs."""
    root = tmp_path_factory.mktemp("quick")
    suite_file = root / "quick-short.yaml"
    values = yaml.safe_load(suite_path("quick").read_text())
    for dataset in values["datasets"]:
        data = dataset.get("data", {})
        for key, value in SHORTER.items():
            if key in data:
                data[key] = min(value, data[key])
        if dataset["name"] == "kitti-imu-gps":
            data["duration_s"] = 10
    suite_file.write_text(yaml.safe_dump(values))
    out = root / "bench"
    assert main(["bench", str(suite_file), "--runs", "2", "--out", str(out), "--no-plots"]) == 0
    figures = {}
    with plt.rc_context({"figure.max_open_warning": 0}):  # every figure is kept to be inspected
        for dataset in sorted((out / "runs").iterdir()):
            folders = sorted(p.parent for p in dataset.glob("*/seed-*/metrics.json"))
            pairs = summarize([read_run(folder) for folder in folders])
            figures[dataset.name] = (pairs, dataset_figures(pairs, dataset.name))
        yield figures
    plt.close("all")


def _curves(axes) -> list[tuple[str, str, str]]:
    """(estimator, colour, label) of every estimator curve in ``axes``."""
    owner = _estimator_in(axes.get_title()) or _estimator_in(axes.get_ylabel())
    found = []
    for line in axes.get_lines():
        label = line.get_label()
        estimator = _estimator_in(label)
        if estimator is None and owner is not None and not label.startswith("reference"):
            estimator = owner  # a row or panel of one estimator: causal/smoothed, x/y/z
        if estimator is None:
            continue
        found.append((estimator, mcolors.to_hex(line.get_color()), label))
    return found


def test_each_estimator_has_one_colour_in_every_axes_of_every_figure(quick_figures) -> None:
    colours: dict[str, set[str]] = {}
    checked = 0
    for _, figures in quick_figures.values():
        for _, figure in figures:
            for axes in figure.axes:
                for estimator, colour, _ in _curves(axes):
                    colours.setdefault(estimator, set()).add(colour)
                    checked += 1
    assert checked > 200
    assert set(colours) == {entry.name for entry in ESTIMATORS}
    for estimator, seen in colours.items():
        assert seen == {estimator_style(estimator).color}, (estimator, seen)
    assert len({next(iter(seen)) for seen in colours.values()}) == len(colours)


def test_causal_is_solid_and_smoothed_dashed(quick_figures) -> None:
    kinds = set()
    for _, figures in quick_figures.values():
        for name, figure in figures:
            if name not in ("trajectories", "consistency"):
                continue
            for axes in figure.axes:
                for line in axes.get_lines():
                    label = line.get_label()
                    if label == "causal" or (_estimator_in(label) and " smoothed" not in label):
                        assert line.get_linestyle() == "-", label
                        kinds.add("causal")
                    elif label == "smoothed" or " smoothed (" in label:
                        assert line.get_linestyle() == "--", label
                        kinds.add("smoothed")
    assert kinds == {"causal", "smoothed"}


def _named(figure) -> set[str | None]:
    """Every estimator a figure names: in titles, y labels, texts and legends."""
    texts = [axes.get_title() for axes in figure.axes] + [axes.get_ylabel() for axes in figure.axes]
    texts += [text.get_text() for axes in figure.axes for text in axes.texts]
    legends = [axes.get_legend() for axes in figure.axes if axes.get_legend() is not None]
    texts += [text.get_text() for legend in [*legends, *figure.legends] for text in legend.texts]
    return {_estimator_in(text) for text in texts}


def test_no_estimator_that_ran_is_left_out_of_a_per_estimator_figure(quick_figures) -> None:
    for dataset, (pairs, figures) in quick_figures.items():
        ran = {pair.estimator for pair in pairs if pair.finished_runs}
        by_name = dict(figures)
        assert "trajectories" in by_name, dataset
        for name in ("trajectories", "position_error", "pose_errors"):
            if name in by_name:
                named = _named(by_name[name])
                assert ran <= named, (dataset, name, ran - named)
