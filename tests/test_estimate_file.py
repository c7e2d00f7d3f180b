"""``estimate.npz`` reads back into the ``Estimate`` that was written, for every registered
estimator (histories, blocks with their frames, map snapshots, the final map with its joint
covariance, diagnostics, extras, events, notes)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.estimate import Diagnostics, Estimate
from datasets.state import LandmarkMap, StateHistory
from datasets.trajectory import Trajectory
from workbench.registry import ESTIMATORS

DATASET = {"sim:circle": {"duration_s": 2}, "sim:guerreiro-loop": {"duration_s": 4}}


def _assert_same(written, read, where: str) -> None:
    """Field by field, arrays exactly (NaN equal to NaN)."""
    if dataclasses.is_dataclass(written) and not isinstance(written, type):
        assert type(read) is type(written), where
        for field in dataclasses.fields(written):
            if field.name == "timing":
                continue  # compared below, on its own
            _assert_same(
                getattr(written, field.name), getattr(read, field.name), f"{where}.{field.name}"
            )
    elif isinstance(written, dict):
        assert {str(k) for k in written} == {str(k) for k in read}, where
        for key in written:
            _assert_same(written[key], read[key], f"{where}[{key}]")
    elif isinstance(written, tuple | list):
        assert len(written) == len(read), where
        for index, (a, b) in enumerate(zip(written, read, strict=True)):
            _assert_same(a, b, f"{where}[{index}]")
    elif isinstance(written, np.ndarray):
        assert np.array_equal(written, np.asarray(read), equal_nan=written.dtype.kind == "f"), where
    elif isinstance(written, float) and isinstance(read, float):
        assert written == read or (np.isnan(written) and np.isnan(read)), where
    else:
        assert written == read, (where, written, read)


@pytest.mark.parametrize("estimator", [entry.name for entry in ESTIMATORS])
def test_the_estimate_reads_back_as_written(estimator: str, tmp_path: Path) -> None:
    from workbench import load_estimate, run

    dataset = "sim:circle" if estimator == "aghili" else "sim:guerreiro-loop"
    done = run(estimator, dataset, seed=1, data=DATASET[dataset], out=tmp_path / "run")
    written, read = done.estimate, load_estimate(done.folder)
    # the map snapshots are kept without their joint covariance (module docstring)
    for history in (written.causal, written.smoothed):
        if history is not None:
            object.__setattr__(
                history,
                "landmarks",
                tuple(dataclasses.replace(m, joint_covariance=None) for m in history.landmarks),
            )
    # events are stored as JSON: numpy scalars in their details come back as Python numbers
    written = dataclasses.replace(
        written,
        diagnostics=dataclasses.replace(
            written.diagnostics,
            events=tuple(
                dataclasses.replace(
                    event,
                    details={
                        k: (v.item() if isinstance(v, np.generic) else v)
                        for k, v in event.details.items()
                    },
                )
                for event in written.diagnostics.events
            ),
        ),
    )
    _assert_same(written, read, estimator)
    assert np.array_equal(written.timing.seconds, read.timing.seconds)
    if written.landmarks is not None and written.landmarks.joint_covariance is not None:
        assert read.landmarks.joint_covariance.shape == written.landmarks.joint_covariance.shape


def test_a_version_1_file_and_a_bad_folder(tmp_path: Path) -> None:
    from workbench.results.estimate_file import estimate_arrays, read_estimate

    pose = Trajectory(np.arange(3.0), np.zeros((3, 2)), np.zeros(3))
    empty = np.zeros(0)
    estimate = Estimate(
        causal=StateHistory(pose=pose, landmarks=(LandmarkMap(np.array([1]), np.zeros((1, 2))),)),
        diagnostics=Diagnostics(*([empty] * 14)),
    )
    arrays = estimate_arrays(estimate)
    version_1 = {
        key: value
        for key, value in arrays.items()
        if key not in ("format_version", "smoothed_present") and "map_" not in key
    }
    np.savez(tmp_path / "estimate.npz", **version_1)
    read = read_estimate(tmp_path)
    assert read.smoothed is None and read.causal.landmarks == ()
    assert np.array_equal(read.causal.pose.t, pose.t)
    with pytest.raises(InputError, match="no estimate.npz"):
        read_estimate(tmp_path / "nowhere")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "estimate.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="not a readable estimate file"):
        read_estimate(tmp_path / "bad")
