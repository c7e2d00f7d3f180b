"""Figures like Guerreiro et al. (2013) Fig. 2(a) and Fig. 4 for a sensor-based run folder.

Reads the run folder's ``estimate.npz``-independent inputs by re-running nothing: it runs
the filter with the given options on the given dataset and writes into ``--out``
(typically the ``workbench run`` folder of the same run):

- ``fig2_vehicle_std.png``: standard deviation of the vehicle variables (velocity x, y;
  gyro bias) over time, log scale (the paper's Fig. 2(a): uncertainty decreasing);
- ``fig4_nis.png``: per scan, the maximum and the average NIS of the associations with the
  95 % chi-square threshold (the paper's Fig. 4, eq. (11)).

    /work/venv/bin/python benchmarks/plot_sensor_based_figures.py --out RUN_DIR \
        [--dataset sim:guerreiro-loop] [--seed 0] [--set key=value ...] [--data key=value ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.stats import chi2  # noqa: E402

from datasets.options import yaml_value  # noqa: E402
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam  # noqa: E402
from workbench.registry import load_dataset  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--dataset", default="sim:guerreiro-loop")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", nargs="*", default=[])
    parser.add_argument("--data", nargs="*", default=[])
    args = parser.parse_args()
    overrides = {k: yaml_value(v) for k, v in (item.split("=", 1) for item in args.set)}
    sequence = load_dataset(args.dataset, args.seed, dict(item.split("=", 1) for item in args.data))
    estimator = SensorBasedSlam(SensorBasedConfig(**{"association": "jcbb", **overrides}), sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    estimate = estimator.estimate()
    args.out.mkdir(parents=True, exist_ok=True)

    extras = estimate.diagnostics.extras
    t = extras["vehicle_t"]
    nv = extras["vehicle_state"].shape[1]
    std = np.sqrt(
        np.diagonal(extras["vehicle_covariance"].reshape(len(t), nv, nv), axis1=1, axis2=2)
    )
    figure, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    d = sequence.dimension
    for k in range(d):
        axes[0].semilogy(t, std[:, k], label=f"v[{k}]")
    axes[0].set_ylabel("std [m/s]")
    for k in range(d, nv):
        axes[1].semilogy(t, np.degrees(std[:, k]), label=f"b[{k - d}]")
    axes[1].set_ylabel("std [deg/s]")
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title(
        f"{args.dataset}: vehicle-variable uncertainty (cf. Guerreiro et al. Fig. 2a)"
    )
    figure.tight_layout()
    figure.savefig(args.out / "fig2_vehicle_std.png", dpi=120)
    plt.close(figure)

    diagnostics = estimate.diagnostics
    times = np.unique(diagnostics.nis_t)
    maximum = np.array([diagnostics.nis[diagnostics.nis_t == s].max() for s in times])
    average = np.array([diagnostics.nis[diagnostics.nis_t == s].mean() for s in times])
    dof = int(np.max(diagnostics.nis_dof)) if len(diagnostics.nis_dof) else d
    figure, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(times, maximum, color="C3", linewidth=0.7, label="maximum NIS")
    ax.plot(times, average, color="C0", linewidth=0.7, label="average NIS")
    ax.axhline(chi2.ppf(0.95, dof), color="k", linestyle="-.", label=f"chi2 95% ({dof} dof)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("NIS")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{args.dataset}: NIS of the associations (cf. Fig. 4, eq. (11))")
    figure.tight_layout()
    figure.savefig(args.out / "fig4_nis.png", dpi=120)
    plt.close(figure)
    inside = np.mean(average <= chi2.ppf(0.95, dof))
    print(f"wrote {args.out / 'fig2_vehicle_std.png'} and {args.out / 'fig4_nis.png'}")
    print(
        f"average NIS per scan below the 95% threshold: {100 * inside:.1f}% of {len(times)} scans; overall mean NIS {np.mean(diagnostics.nis):.3f} ({dof} dof)"
    )
    print(f"vehicle std first/last: {std[0]} -> {std[-1]}")


if __name__ == "__main__":
    main()
