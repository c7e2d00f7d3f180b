"""``workbench bench-speed`` runs and reports its named figures (no timing asserts: speed
is measured by the command, not judged by the tests)."""

from __future__ import annotations

import json

from workbench.cli import main
from workbench.commands.bench_speed import ratio_rows


def test_bench_speed_writes_the_named_figures_as_json(tmp_path, capsys) -> None:
    out = tmp_path / "speed.json"
    status = main(
        [
            "bench-speed",
            "--only",
            "aghili_propagate_us_n10",
            "--only",
            "ekf_slam_update_ms",
            "--json",
            str(out),
        ]
    )
    assert status == 0
    found = json.loads(out.read_text())
    assert set(found) == {"aghili_propagate_us_n10", "ekf_slam_update_ms"}
    assert all(value > 0 for value in found.values())
    assert "aghili_propagate_us_n10" in capsys.readouterr().out


def test_unknown_figure_is_an_input_error(capsys) -> None:
    assert main(["bench-speed", "--only", "warp_drive_ms"]) == 2
    assert "warp_drive_ms" in capsys.readouterr().err


def test_ratios_pair_figures_of_the_same_run() -> None:
    rows = dict(
        (label, value)
        for label, value, _ in ratio_rows({"filterpy_update_ms": 15.0, "aghili_update_ms": 1.5})
    )
    assert rows["filterpy / aghili scan update"] == 10.0
    assert rows["filterpy / ekf-slam scan update"] is None  # ekf-slam not measured
    per_hypothesis = ratio_rows(
        {"ekf_slam_mht_hypothesis_scan_ms_loop": 3.0, "ekf_slam_scan_ms_loop": 2.0}
    )
    assert per_hypothesis == [("ekf-slam-mht per hypothesis / ekf-slam, per scan", 1.5, "<= 2")]
