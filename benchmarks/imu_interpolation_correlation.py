"""Why the IMU smoothers' *smoothed* velocity reads slightly conservative on the rover.

A study, not a test: it prints exact ratios (no sampling) for a linear-Gaussian stand-in.

The smoothers integrate instantaneous IMU samples with the straight line between two
samples (``smoothers/imu_graph.py``): over the sample interval ``[t_i, t_i + dt)`` the
acceleration is ``(a_i + a_{i+1}) / 2``. A keyframe at a sample time therefore shares that
sample between the factor before it and the factor after it. GTSAM models each factor's
increment as independent with the continuous density's covariance (``q^2 T`` for the
velocity increment over a keyframe interval ``T``). The truth's increments are correlated
(the shared sample), and each one's own variance is ``q^2 (T - dt/2)``, not ``q^2 T``.
Over many intervals the two effects cancel (a causal estimate integrates the increments),
but a smoothed estimate at a keyframe differences the increments on its two sides, where
they do not.

The stand-in: a 1-D double integrator, IMU samples every ``dt`` with white noise of
density ``q`` (variance ``q^2 / dt`` per sample, the simulator's rule), keyframes every
``T`` with a position measurement of std ``sigma_p``. The smoother is the weighted least
squares with the model's independent increment covariances; its true error covariance is
``L C L^T`` with ``L`` its gain and ``C`` the truth's noise covariance. The ratio true /
stated variance is what the velocity NEES per dof reads over many runs.

Usage: ``python benchmarks/imu_interpolation_correlation.py``. ``sim:aghili-rover``:
IMU 20 Hz, keyframes 10 Hz, ``q`` = 0.01 m/s^2/sqrt(Hz), about 15 landmarks of 0.1-0.25 m
in view (``sigma_p`` about 0.02-0.05 m); ``sim:circle`` the same at 100 Hz.
"""

from __future__ import annotations

import numpy as np


def increment_map(
    keyframes: int, samples_per_keyframe: int, dt: float, interpolate: bool = True
) -> np.ndarray:
    """Each keyframe interval's (dp, dv) as a linear map of the IMU samples' noise.

    ``interpolate=False`` is the zero-order hold (each step uses its first sample only):
    the increments are then independent, the control of the study.

    Returns: (2 keyframes, keyframes * samples_per_keyframe + 1) [s^2, s].
    """
    interval = samples_per_keyframe * dt
    sample_count = keyframes * samples_per_keyframe + 1
    mapping = np.zeros((2 * keyframes, sample_count))
    for keyframe in range(keyframes):
        for step in range(samples_per_keyframe):
            first = keyframe * samples_per_keyframe + step
            time_left = interval - (step + 1) * dt
            ends = (first, first + 1) if interpolate else (first,)
            for sample in ends:  # the step's value is the mean of its ends
                mapping[2 * keyframe + 1, sample] += dt / len(ends)
                mapping[2 * keyframe, sample] += (dt**2 / 2 + dt * time_left) / len(ends)
    return mapping


def true_over_stated(
    density: float,
    sigma_p: float,
    imu_dt: float,
    keyframe_dt: float = 0.1,
    keyframes: int = 150,
    interpolate: bool = True,
) -> dict[str, float]:
    """Exact true/stated variance ratios of the middle keyframe (smoothed) and of the
    newest keyframe of the first half (causal)."""
    samples_per_keyframe = int(round(keyframe_dt / imu_dt))
    transition = np.array([[1.0, keyframe_dt], [0.0, 1.0]])
    model_increment = density**2 * np.array(
        [[keyframe_dt**3 / 3, keyframe_dt**2 / 2], [keyframe_dt**2 / 2, keyframe_dt]]
    )
    state_count = 2 * (keyframes + 1)
    row_count = 2 * keyframes + keyframes + 1
    jacobian = np.zeros((row_count, state_count))
    weight = np.zeros((row_count, row_count))
    truth_noise = np.zeros((row_count, row_count))
    for keyframe in range(keyframes):
        rows = slice(2 * keyframe, 2 * keyframe + 2)
        jacobian[rows, 2 * keyframe + 2 : 2 * keyframe + 4] = np.eye(2)
        jacobian[rows, 2 * keyframe : 2 * keyframe + 2] = -transition
        weight[rows, rows] = np.linalg.inv(model_increment)
    mapping = increment_map(keyframes, samples_per_keyframe, imu_dt, interpolate)
    truth_noise[: 2 * keyframes, : 2 * keyframes] = mapping @ mapping.T * density**2 / imu_dt
    for keyframe in range(keyframes + 1):
        row = 2 * keyframes + keyframe
        jacobian[row, 2 * keyframe] = 1.0
        weight[row, row] = 1.0 / sigma_p**2
        truth_noise[row, row] = sigma_p**2

    def ratios(last: int) -> tuple[np.ndarray, np.ndarray]:
        rows = list(range(2 * last)) + [2 * keyframes + k for k in range(last + 1)]
        columns = list(range(2 * (last + 1)))
        used = jacobian[np.ix_(rows, columns)]
        used_weight = weight[np.ix_(rows, rows)]
        stated = np.linalg.inv(used.T @ used_weight @ used)
        gain = stated @ used.T @ used_weight
        return gain @ truth_noise[np.ix_(rows, rows)] @ gain.T, stated

    middle = keyframes // 2
    true_all, stated_all = ratios(keyframes)
    true_causal, stated_causal = ratios(middle)
    velocity = 2 * middle + 1
    return {
        "smoothed velocity": true_all[velocity, velocity] / stated_all[velocity, velocity],
        "smoothed position": true_all[velocity - 1, velocity - 1]
        / stated_all[velocity - 1, velocity - 1],
        "causal velocity": true_causal[velocity, velocity] / stated_causal[velocity, velocity],
    }


def main() -> None:
    print("true / stated variance (what NEES per dof reads), keyframes at 10 Hz")
    print(f"{'q':>6} {'sigma_p':>8} {'IMU':>7}  smoothed v  smoothed p  causal v")
    for density in (0.01, 0.1):
        for sigma_p in (0.02, 0.05, 0.2):
            for imu_hz in (20.0, 100.0):
                keyframes = 150 if imu_hz <= 20 else 60
                result = true_over_stated(density, sigma_p, 1.0 / imu_hz, keyframes=keyframes)
                print(
                    f"{density:6.2f} {sigma_p:8.2f} {imu_hz:5.0f}Hz"
                    f"  {result['smoothed velocity']:10.3f}  {result['smoothed position']:10.3f}"
                    f"  {result['causal velocity']:8.3f}"
                )
    control = true_over_stated(0.01, 0.02, 0.05, interpolate=False)
    print(
        "control, zero-order hold (independent increments), q 0.01, sigma_p 0.02, 20 Hz:"
        f"  {control['smoothed velocity']:.3f}  {control['smoothed position']:.3f}"
        f"  {control['causal velocity']:.3f}"
    )


if __name__ == "__main__":
    main()
