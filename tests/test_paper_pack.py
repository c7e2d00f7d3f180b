"""``workbench report RUNS --paper DIR``: the pack's files, an ``evaluation.tex`` whose facts
come from the runs and the code, the folder's safety; and (a study, where pdflatex is
installed) the quick and consistency suites' tables and ``evaluation.tex`` compiled into a
plain one-column article without an overfull box."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from workbench.cli import main
from workbench.metrics.timestamps import DEFAULT_MAX_DIFF_S
from workbench.metrics.verdicts import MIN_POOLED_UPDATES, MIN_RUNS
from workbench.results.columns import PRESETS
from workbench.suite_files import suite_path

FORBIDDEN = re.compile(r"\\(resizebox|scalebox|tiny|scriptsize)\b")


@pytest.fixture(scope="module")
def tiny_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny suite's ekf-slam, 2 runs, no figures: a few seconds."""
    out = tmp_path_factory.mktemp("tiny") / "bench"
    argv = ["bench", "tiny", "--runs", "2", "--estimator", "ekf-slam", "--no-plots"]
    assert main([*argv, "--out", str(out)]) == 0
    return out


def test_a_paper_pack_states_the_protocol_of_its_runs(tiny_runs: Path, tmp_path, capsys):
    pack = tmp_path / "pack"
    assert main(["report", str(tiny_runs), "--paper", str(pack), "--no-plots"]) == 0
    printed = capsys.readouterr().out
    assert f"paper pack: {pack}" in printed
    assert not (tmp_path / "report").exists()  # --paper alone writes the pack only
    for name in PRESETS:
        text = (pack / "tables" / f"{name}.tex").read_text()
        assert "\\begin{table}" in text and "\\caption{" in text and not FORBIDDEN.search(text)
    assert (pack / "tables" / "table.csv").is_file() and not (pack / "figures").exists()
    evaluation = (pack / "evaluation.tex").read_text()
    assert not FORBIDDEN.search(evaluation) and "\\documentclass" not in evaluation
    metrics = json.loads(next((tiny_runs / "runs").rglob("metrics.json")).read_text())
    revision = metrics["git_revision"].removesuffix("+dirty")
    versions = metrics["package_versions"]
    # facts of the runs: estimators, options, seeds, references, alignment, versions
    for fact in (
        "Estimators (1): \\texttt{ekf-slam}",
        "\\emph{sim:circle}",
        "\\texttt{duration\\_s=4}",
        "\\texttt{duration\\_s=8}",
        "2 runs per estimator (seeds 0, 1)",
        f"reference: {metrics['reference_source']}",
        "SE(3) Umeyama",  # sim:circle has an IMU: 3-D
        "SE(2) Umeyama",  # sim:guerreiro-loop is planar
        "delta = 1 (frames)",
        f"\\texttt{{{revision}}}",
        f"numpy~{versions['numpy']}",
        f"gtsam~{versions['gtsam']}",
    ):
        assert fact in evaluation, fact
    # facts of the code: pairing tolerance, verdict rule
    for fact in (
        f"within {DEFAULT_MAX_DIFF_S:g}\\,s",
        f"a NEES cell needs {MIN_RUNS} runs",
        f"a NIS cell {MIN_POOLED_UPDATES} updates",
        "$e^\\top P^{-1} e$",
        "Dof per step in these runs: pose",
    ):
        assert fact in evaluation, fact
    # a pack written again with one table keeps no other table of the earlier one
    assert main(["report", str(tiny_runs), "--paper", str(pack), "--no-plots", "--table",
                 "accuracy"]) == 0  # fmt: skip
    assert sorted(p.name for p in (pack / "tables").glob("*.tex")) == ["accuracy.tex"]


def test_a_paper_pack_never_writes_into_a_folder_of_the_users(tiny_runs, tmp_path, capsys):
    mine = tmp_path / "thesis"
    mine.mkdir()
    (mine / "thesis.tex").write_text("\\documentclass{article}\n")
    assert main(["report", str(tiny_runs), "--paper", str(mine), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --paper") and err.count("\n") == 1 and "thesis.tex" in err
    assert [p.name for p in mine.iterdir()] == ["thesis.tex"]


def _shortened(name: str, folder: Path) -> Path:
    """A built-in suite as a user would shorten it (its own YAML, durations cut)."""
    values = yaml.safe_load(suite_path(name).read_text())
    for dataset in values["datasets"]:
        data = dataset.setdefault("data", {})
        if dataset["name"] == "kitti-imu-gps":
            data["duration_s"] = 10
        elif dataset["name"] == "victoria-park":
            data["max_steps"] = 150
        else:
            data["duration_s"] = min(4, data.get("duration_s", 4))
    path = folder / f"{name}-short.yaml"
    path.write_text(yaml.safe_dump(values))
    return path


def _compile(folder: Path, inputs: list[str], graphics: list[Path], paper: str) -> str:
    """pdflatex of a plain one-column article \\input-ing ``inputs``; returns the log."""
    lines = [
        f"\\documentclass[{paper}]{{article}}",
        "\\usepackage[margin=1in]{geometry}",
        "\\usepackage{booktabs,amssymb,graphicx}",
        "\\begin{document}",
        *(f"\\input{{{name}}}" for name in inputs),
        # noindent: a paragraph indent beside a full-width figure would be an overfull box
        *(f"\\noindent\\includegraphics[width=\\textwidth]{{{path}}}" for path in graphics),
        "\\end{document}",
    ]
    (folder / "paper.tex").write_text("\n".join(lines) + "\n")
    done = subprocess.run(
        ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "paper.tex"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=300,
    )
    log = (folder / "paper.log").read_text(errors="replace")
    assert done.returncode == 0, log[-3000:]
    return log


@pytest.mark.study
@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex is not installed (TeX)")
@pytest.mark.parametrize(
    ("suite", "options"),
    [
        ("quick", []),
        # the consistency suite's labels and NEES cells (its smoothed ˢ cells are the widest);
        # its figures are the quick suite's kind: drawn once, above
        ("consistency", ["--estimator", "ekf-slam", "--estimator", "smoother-batch"]),
    ],
)
def test_the_pack_compiles_into_a_one_column_article_without_overfull_boxes(
    tmp_path: Path, suite: str, options: list[str]
) -> None:
    runs = tmp_path / "runs"
    suite_file = _shortened(suite, tmp_path)
    argv = ["bench", str(suite_file), "--runs", "2", "--no-plots", "--out", str(runs)]
    assert main([*argv, *options]) == 0
    pack = tmp_path / "pack"
    figures_too = suite == "quick"
    report = ["report", str(runs), "--paper", str(pack)]
    assert main(report if figures_too else [*report, "--no-plots"]) == 0
    tables = sorted((pack / "tables").glob("*.tex"))
    assert [p.stem for p in tables] == sorted(PRESETS)
    figures = sorted((pack / "figures").rglob("*.pdf"))
    if figures_too:  # a folder of PDF figures per dataset
        datasets = {p.parent.name for p in figures}
        assert len(datasets) == len(list((runs / "runs").iterdir()))
    for path in [*tables, pack / "evaluation.tex"]:
        assert not FORBIDDEN.search(path.read_text()), path
    inputs = [f"tables/{p.stem}" for p in tables] + ["evaluation"]
    for paper in ("letterpaper", "a4paper"):
        log = _compile(pack, inputs, figures[:1], paper)
        assert "Overfull \\hbox" not in log, re.findall(r"Overfull \\hbox.*", log)
        assert "Output written on paper.pdf" in log
