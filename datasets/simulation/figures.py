"""Summary figures of a simulated sequence: how long, how far, how many landmarks seen.

``python -m datasets.simulation.figures [SEED]`` prints them for every scenario.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from datasets.measurements import LandmarkScan
from datasets.sequence import Sequence
from datasets.state import BlockName


def sequence_figures(sequence: Sequence) -> dict[str, float | int]:
    """Path length [m], duration [s], mean speed [m/s], landmarks in the world, and the
    mean / min / max number of landmarks per scan (scan count included)."""
    truth = sequence.ground_truth
    counts = np.array([m.count for m in sequence.measurements() if isinstance(m, LandmarkScan)])
    speed = np.linalg.norm(truth.history.block(BlockName.VELOCITY).values, axis=1)
    return {
        "path_length_m": round(truth.pose.path_length(), 2),
        "duration_s": round(float(truth.pose.t[-1] - truth.pose.t[0]), 2),
        "mean_speed_m_s": round(float(np.mean(speed)), 3),
        "landmarks": len(truth.landmarks),
        "scans": int(len(counts)),
        "visible_mean": round(float(np.mean(counts)), 2),
        "visible_min": int(np.min(counts)),
        "visible_max": int(np.max(counts)),
        "start_to_end_m": round(
            float(np.linalg.norm(truth.pose.positions[-1] - truth.pose.positions[0])), 2
        ),
    }


def main(arguments: list[str]) -> None:
    from datasets.simulation.scenarios import SCENARIO_NAMES, load_scenario

    seed = int(arguments[0]) if arguments else 0
    for name in SCENARIO_NAMES:
        print(f"sim:{name}", json.dumps(sequence_figures(load_scenario(name, seed, {}))))


if __name__ == "__main__":
    main(sys.argv[1:])
