"""evo result files of a run: ``ape.zip`` and ``rpe.zip`` (and ``*_smoothed.zip``) in the
layout ``evo_res`` reads as they are (``evo.tools.file_interface.load_res_file``: a zip of
``info.json``, ``stats.json``, ``error_array.npy``, ``timestamps.npy``), so evo users can
keep and merge the workbench's results with theirs.

The figures are the workbench's own (``workbench.metrics``), computed as evo computes them:
APE of the translation part after alignment (SE(3) in 3-D, SE(2) for planar runs: evo's
``--align --project_to_plane xy`` equivalent), RPE of the translation part over 1 frame
without alignment. Their RMSE equals metrics.json's ``ate_rmse_m`` and ``rpe_trans_rmse_m``,
exclusions included: given the truth's ``excluded`` intervals, the reference loses its
samples inside them before pairing, the estimate its poses inside them, and the RPE its
pairs whose interval meets one (``workbench.metrics.summary``).
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from datasets.trajectory_io import write_atomic
from workbench.metrics.ate import error_statistics
from workbench.metrics.summary import ScoredPairs

MIN_POSES = 3
"""Fewer paired poses than this give no result (an alignment needs three)."""


def evo_statistics(errors: np.ndarray) -> dict[str, float]:
    """The statistics evo stores in ``stats.json`` (its ``StatisticsType`` names)."""
    errors = np.asarray(errors, dtype=float)
    return {**error_statistics(errors), "sse": float(np.sum(errors**2))}


def result_zip(info: dict[str, str], errors: np.ndarray, timestamps: np.ndarray) -> bytes:
    """One evo result file as bytes."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("info.json", json.dumps(info))
        archive.writestr("stats.json", json.dumps(evo_statistics(errors)))
        for name, array in (("error_array", errors), ("timestamps", timestamps)):
            array_buffer = io.BytesIO()
            np.save(array_buffer, np.asarray(array, dtype=float))
            archive.writestr(f"{name}.npy", array_buffer.getvalue())
    return buffer.getvalue()


def write_evo_results(folder: Path, scored: ScoredPairs, name: str, suffix: str = "") -> list[str]:
    """Write ``ape{suffix}.zip`` and ``rpe{suffix}.zip`` into ``folder`` from the pairs the
    run's metrics.json is computed on (``workbench.metrics.summary.scored_pairs``: one
    computation for both, exclusions and non-finite truth rows included), the estimate
    labelled ``name`` (``evo_res`` wants the labels of the results it compares distinct);
    returns the files written (none when fewer than ``MIN_POSES`` poses pair)."""
    if len(scored.estimate) < MIN_POSES:
        return []
    label = "SE(3)" if scored.align == "se3" else "SE(2)"
    ape = {
        "title": f"APE w.r.t. translation part (m)\n(with {label} Umeyama alignment)",
        "ref_name": "reference",
        "est_name": name,
        "label": "APE (m)",
    }
    write_atomic(folder / f"ape{suffix}.zip", result_zip(ape, scored.ate, scored.estimate.t))
    written = [f"ape{suffix}.zip"]
    if len(scored.rpe_trans) == 0:
        return written  # every consecutive pair spans an excluded interval
    rpe = {
        "title": "RPE w.r.t. translation part (m)\nfor delta = 1 (frames) using consecutive pairs\n(not aligned)",
        "ref_name": "reference",
        "est_name": name,
        "label": "RPE (m)",
    }
    times = scored.estimate.t[scored.rpe_pairs[:, 1]]
    write_atomic(folder / f"rpe{suffix}.zip", result_zip(rpe, scored.rpe_trans, times))
    written.append(f"rpe{suffix}.zip")
    return written
