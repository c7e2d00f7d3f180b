"""Speed figures of the smoothers for ``workbench bench-speed`` (``workbench.speed``), kept
in the application, not in the ``smoothers`` library.

The scene (``benchmarks/bench_smoother.py``'s landmark scaling): ``sim:circle`` (100 Hz IMU,
10 Hz scans with ids) with 200 landmarks around the circle, 155-160 of them in view at every
scan (170 seen in the 3 s), anchored by 3 known landmarks: the dense worst case of a
keyframe update (31 keyframes).

Measured on this 2-core machine (``OPENBLAS_NUM_THREADS=1``, 2026-11): ``isam2_keyframe_ms``
24-26 ms with Cholesky, 400-430 ms with QR (about 1.5 s and 13 s to measure);
``smoother_finish_s`` 0.48 s (about 4 s to measure), against 11.6-12.2 s for the per-key
marginal queries of the code before issue 12.
"""

from __future__ import annotations

import time

import numpy as np

from datasets.sequence import Sequence

SCENE_SECONDS = "3"


def circle_scene(landmarks: int, seconds: str = SCENE_SECONDS) -> Sequence:
    """``sim:circle`` with ``landmarks`` landmarks, all in view, ``seconds`` long."""
    from datasets.simulation.scenarios import load_scenario

    return load_scenario("circle", 1, {"duration_s": seconds, "landmark_count": str(landmarks)})


def isam2_keyframe_ms(landmarks: int = 200, factorization: str = "CHOLESKY") -> float:
    """Median wall-clock time of one keyframe of ``SmootherIsam2`` (scan association by ids,
    factors, the iSAM2 update, the causal record) [ms], with iSAM2's ``factorization``
    (``CHOLESKY`` or ``QR``). Without the scan's prediction (no NIS, no id gate): this
    figure compares factorisations; with 160 landmarks in view the prediction's joint
    marginal query adds about 45 ms per keyframe (Cholesky) and the causal marginals of the
    keyframe's states about 170 ms."""
    from smoothers.modes import SmootherIsam2

    sequence = circle_scene(landmarks)
    smoother = SmootherIsam2(
        SmootherIsam2.Config(
            anchors=3,
            causal_covariances=False,
            factorization=factorization,
            innovation_nis=False,
            id_gate_probability=None,
        ),
        sequence,
    )
    keyframes = len(smoother.keyframe_t)
    per_keyframe: list[float] = []
    pending = 0.0
    for measurement in sequence.measurements():
        start = time.perf_counter()
        smoother.process(measurement)
        pending += time.perf_counter() - start
        if len(smoother.keyframe_t) != keyframes:
            per_keyframe.append(pending)
            pending, keyframes = 0.0, len(smoother.keyframe_t)
    return 1e3 * float(np.median(per_keyframe))


def smoother_finish_s(landmarks: int = 200) -> float:
    """Seconds of ``SmootherIsam2.estimate()`` at the end of the scene: the smoothed history
    of every keyframe and the final map, with marginal covariances."""
    from smoothers.modes import SmootherIsam2

    sequence = circle_scene(landmarks)
    smoother = SmootherIsam2(SmootherIsam2.Config(anchors=3, causal_covariances=False), sequence)
    for measurement in sequence.measurements():
        smoother.process(measurement)
    start = time.perf_counter()
    smoother.estimate()
    return time.perf_counter() - start
