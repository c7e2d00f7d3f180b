"""Typed data, one way (issue #39): what one layer reads of a ``Sequence`` is a typed field,
never a key of its free ``metadata``; what a pass over a bag's stream finds is a
``PassReport`` that the pass fills; the run's description of the source
(``config.yaml``'s ``dataset_metadata``) is built from both with the keys it always had."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest
import yaml

from datasets.pass_report import PassReport
from datasets.sequence import Sequence, split_description
from datasets.simulation.folder_format import read_sequence_folder, write_sequence_folder
from datasets.simulation.scenarios import load_scenario
from datasets.synthetic_lidar import write_lidar_bag
from workbench.cli import main
from workbench.registry import load_dataset

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("datasets", "filters", "smoothers", "workbench")
KEY_READS = {"get", "items", "keys", "values", "__getitem__", "__contains__"}


def metadata_reads(source: str) -> list[int]:
    """Lines of ``source`` that read keys of an attribute called ``metadata``
    (``x.metadata[...]``, ``x.metadata.get(...)``, ``.items()``/``.keys()``/``.values()``,
    ``k in x.metadata``); a write (``x.metadata[k] = v``) or a local dict called
    ``metadata`` is no read of a ``Sequence``'s."""

    def is_metadata(node: ast.AST) -> bool:
        return isinstance(node, ast.Attribute) and node.attr == "metadata"

    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Load):
            hit = is_metadata(node.value)
        elif isinstance(node, ast.Attribute) and node.attr in KEY_READS:
            hit = is_metadata(node.value)
        elif isinstance(node, ast.Compare):
            hit = any(
                isinstance(op, ast.In | ast.NotIn) and is_metadata(right)
                for op, right in zip(node.ops, node.comparators)
            )
        else:
            hit = False
        if hit:
            lines.append(node.lineno)
    return sorted(lines)


def test_the_check_finds_every_form_of_read_and_no_write() -> None:
    reads = """
a = sequence.metadata["counts"]
b = result.sequence.metadata.get("reference_source")
c = [k for k, v in sequence.metadata.items()]
d = "warnings" in sequence.metadata
e = sequence.metadata["topics"]["lidar"]
"""
    assert metadata_reads(reads) == [2, 3, 4, 5, 6]
    not_reads = """
metadata = {"source": "x"}
metadata["laser_corners"] = figures
value = metadata.get("source")
sequence.metadata["x"] = 1
version = importlib.metadata.version("numpy")
"""
    assert metadata_reads(not_reads) == []


def test_no_layer_reads_keys_of_a_sequences_metadata() -> None:
    """Not even the loaders: what they write into ``metadata`` is a description, and what
    is read back is a typed field of the ``Sequence``."""
    found = {
        f"{path.relative_to(ROOT)}:{line}"
        for package in PACKAGES
        for path in sorted((ROOT / package).rglob("*.py"))
        for line in metadata_reads(path.read_text())
    }
    assert not found, sorted(found)


def _simulated() -> Sequence:
    return load_scenario("circle", 3, {"duration_s": "5", "ids": "false"})


def test_a_simulated_description_is_its_metadata_and_its_reference(tmp_path) -> None:
    sequence = _simulated()
    assert sequence.reference_source == "simulated truth" and sequence.landmark_ids is False
    assert "reference_source" not in sequence.metadata and "warnings" not in sequence.metadata
    assert sequence.description() == {**sequence.metadata, "reference_source": "simulated truth"}
    assert sequence.all_warnings() == []
    # a simulated folder keeps the description and reads the typed fields back from it
    folder = write_sequence_folder(sequence, tmp_path / "sim")
    stored = json.loads((folder / "sequence.json").read_text())["metadata"]
    assert stored["reference_source"] == "simulated truth"
    loaded = read_sequence_folder(folder)
    assert loaded.metadata == sequence.metadata
    assert (loaded.reference_source, loaded.landmark_ids) == ("simulated truth", False)
    assert loaded.description() == sequence.description()


def test_split_description_inverts_description() -> None:
    sequence = Sequence(
        "x",
        2,
        frozenset(),
        lambda: iter(()),
        metadata={"source": "s", "options": {"ids": True}},
        reference_source=None,
        warnings=("w",),
        counts={"dropped": 2},
        decisions=("d",),
        excluded_truth_s=0.5,
        calibration="c",
        gravity_m_s2=9.8,
    )
    described = sequence.description()
    assert described == {
        "source": "s",
        "options": {"ids": True},
        "reference_source": None,
        "warnings": ["w"],
        "counts": {"dropped": 2},
        "decisions": ["d"],
        "excluded_truth_s": 0.5,
        "calibration": "c",
        "gravity_m_s2": 9.8,
    }
    metadata, typed = split_description(described)
    again = Sequence("x", 2, frozenset(), lambda: iter(()), metadata=metadata, **typed)
    assert metadata == sequence.metadata and again.description() == described
    assert (again.warnings, again.decisions, again.counts) == (("w",), ("d",), {"dropped": 2})


def test_pass_warnings_follow_the_loaders_each_once() -> None:
    report = PassReport.expecting("figures")
    sequence = Sequence(
        "x", 2, frozenset(), lambda: iter(()), warnings=("a", "b"), pass_report=report
    )
    assert sequence.description()["figures"] == {} and report.passes == 0
    report.record(["b", "c"], figures={"n": 1})
    report.record(["c", "d"], figures={"n": 1})
    assert sequence.all_warnings() == ["a", "b", "c", "d"]
    assert report.warnings == ["b", "c", "d"] and report.passes == 2
    assert sequence.description()["warnings"] == ["a", "b", "c", "d"]
    assert sequence.description()["figures"] == {"n": 1}


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory) -> Path:
    """A lidar bag whose IMU starts 50 ms before the lidar: the pass trims it and says so."""
    folder = tmp_path_factory.mktemp("typed")
    options = {"duration_s": "0.6", "columns": "64", "imu_lead_s": "0.05"}
    return write_lidar_bag(folder / "bag", 5, "ros2", options)


def test_a_bag_pass_fills_its_report_once(small_bag, monkeypatch) -> None:
    """...and the bag is opened once to load and once per pass."""
    from rosbags.highlevel import AnyReader

    opened = []
    original = AnyReader.open
    monkeypatch.setattr(AnyReader, "open", lambda self: opened.append(1) or original(self))
    sequence = load_dataset(f"bag:{small_bag}", 0, {"kiss.max_num_threads": "1"})
    assert len(opened) == 1
    report = sequence.pass_report
    assert sequence.topics.lidar == "/points" and sequence.topics.ground_truth is None
    # the simulator's corner sidecar is read, though its poses are not named as truth
    assert sequence.reference_source is None and sequence.corner_sidecar.is_file()
    # before a pass: the figures' keys, empty; no trimmed messages known yet
    assert report.passes == 0 and report.figures == {"kiss_icp": {}, "corner_reobservation": {}}
    before = sequence.description()
    assert before["kiss_icp"] == {} and before["corner_sidecar"] == str(sequence.corner_sidecar)
    assert not any(line.startswith("trimmed") for line in sequence.all_warnings())
    for _ in sequence.measurements():
        pass
    after = sequence.description()
    trimmed = [line for line in sequence.all_warnings() if line.startswith("trimmed")]
    assert report.passes == 1 and len(trimmed) == 1 and "x /imu" in trimmed[0]
    assert len(opened) == 2
    assert after["kiss_icp"]["max_range_m"] > 0 and after["warnings"] == sequence.all_warnings()
    assert set(after) - set(before) == set() and after["topics"] == sequence.topics.as_dict()
    for _ in sequence.measurements():  # a second pass finds the same
        pass
    assert report.passes == 2 and sequence.description() == after and len(opened) == 3


def test_a_bag_run_writes_the_description_and_the_typed_fields(small_bag, tmp_path) -> None:
    """``config.yaml``'s ``dataset_metadata`` holds the keys a bag's always held, the pass's
    figures and warnings filled; ``metrics.json`` the typed fields."""
    out = tmp_path / "run"
    data = ["--data", "ground_truth_topic=/ground_truth", "--data", "kiss.max_num_threads=1"]
    assert main(["run", "dead-reckoning", f"bag:{small_bag}", *data, "--out", str(out)]) == 0
    described = yaml.safe_load((out / "config.yaml").read_text())["dataset_metadata"]
    assert set(described) == {
        "source",
        "reference_source",
        "warnings",
        "topics",
        "time_base",
        "gps_origin",
        "kiss_icp",
        "corner_reobservation",
        "corner_sidecar",
        "options",
        "decisions",
        "sweep_timing",
    }
    assert described["reference_source"] == "topic /ground_truth"
    assert described["corner_sidecar"].endswith("bag.corners.json")
    assert described["kiss_icp"]["max_range_m"] > 0
    assert described["corner_reobservation"]["reobservation_pairs"] >= 0
    assert any(line.startswith("trimmed") for line in described["warnings"])
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["reference_source"] == "topic /ground_truth"
    assert metrics["decisions"] == described["decisions"] and metrics["decisions"]
    assert (metrics["excluded_truth_s"], metrics["calibration"]) == (None, None)
    assert [f"bag:{small_bag}: {line}" for line in described["warnings"]] == [
        line for line in metrics["warnings"] if line.startswith("bag:")
    ]
