"""Victoria Park: how far apart are the smoother's map and the sensor-based filter's map?

Victoria Park has no ground truth, so the incremental smoother's final (smoothed) map is
the reference. Both estimators run on the same stream with the file's landmark ids; every
estimator map id is mapped to the file id it was most often associated with (the
workbench's majority mapping), the sensor-based filter's final body-frame map is put in the
Earth frame with its own final Earth-frame pose (only estimated quantities), and the two
maps are compared on their common landmarks after an SE(2) alignment (Umeyama).

    python benchmarks/victoria_map_agreement.py [--max-steps N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from datasets.rotations import rot2
from workbench.metrics.alignment import umeyama
from workbench.metrics.data_association import landmark_id_mapping
from workbench.registry import estimator_entry, load_dataset
from workbench.runner import resolve_config, run_estimator


def world_map(estimate, sequence) -> dict[int, np.ndarray]:
    """File id -> world-frame landmark position of an estimate's final map."""
    final = estimate.landmarks
    mapping = landmark_id_mapping(estimate.diagnostics, sequence.ground_truth)
    positions = final.positions
    if final.frame == "body":
        pose = estimate.causal.pose
        positions = positions @ rot2(float(pose.rotations[-1])).T + pose.positions[-1]
    return {mapping[int(i)]: p for i, p in zip(final.ids, positions) if int(i) in mapping}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--max-steps", type=int, default=None, help="shorten the file (default: all of it)"
    )
    args = parser.parse_args()
    options = {} if args.max_steps is None else {"max_steps": str(args.max_steps)}
    sequence = load_dataset("victoria-park", 0, options)
    maps = {}
    for name in ("smoother-isam2", "sensor-based"):
        estimator_class = estimator_entry(name).load()
        start = time.perf_counter()
        estimate = run_estimator(estimator_class, resolve_config(estimator_class), sequence)
        maps[name] = world_map(estimate, sequence)
        print(f"{name}: {len(maps[name])} mapped landmarks, {time.perf_counter() - start:.1f} s")
    common = sorted(set(maps["smoother-isam2"]) & set(maps["sensor-based"]))
    reference = np.array([maps["smoother-isam2"][i] for i in common])
    filtered = np.array([maps["sensor-based"][i] for i in common])
    rotation, translation, _ = umeyama(filtered, reference)
    aligned = filtered @ rotation.T + translation
    distances = np.linalg.norm(aligned - reference, axis=1)
    print(f"common landmarks: {len(common)}")
    print(
        f"map agreement after SE(2) alignment: rmse {np.sqrt(np.mean(distances**2)):.3f} m, "
        f"median {np.median(distances):.3f} m, max {distances.max():.3f} m"
    )


if __name__ == "__main__":
    main()
