"""Compare a filter and a smoother on a simulated scenario with the Python API, and make
one figure: the position error of both over time.

    python examples/compare_filter_and_smoother.py [OUT_FOLDER]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from workbench import compare, run  # noqa: E402
from workbench.metrics.state_errors import pose_error_series  # noqa: E402
from workbench.style import estimator_style  # noqa: E402


def main(out: Path) -> None:
    data = {"duration_s": 10}
    runs = {
        name: run(name, "sim:circle", seed=1, data=data, out=out / name)
        for name in ("ekf-slam", "smoother-isam2")
    }
    table = compare([out / name for name in runs])
    print(
        table[["estimator", "ate_rmse_m", "anees_pose_per_dof", "verdict_pose"]].to_string(
            index=False
        )
    )

    figure, axes = plt.subplots(figsize=(6, 3))
    for name, result in runs.items():
        t, errors, _ = pose_error_series(result.estimate.causal.pose, result.sequence.ground_truth)
        # pose errors are [rotation, translation] (the interface's order); the workbench's
        # colour of each estimator, as in every figure it draws
        style = estimator_style(name).keywords(len(t))
        axes.plot(t - t[0], np.linalg.norm(errors[:, 3:6], axis=1), label=name, **style)
    axes.set_xlabel("t - t0 [s]")
    axes.set_ylabel("position error [m] (not aligned)")
    axes.legend()
    figure.tight_layout()
    figure.savefig(out / "position_error.png", dpi=120)
    print(f"figure: {out / 'position_error.png'}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "runs/example"))
