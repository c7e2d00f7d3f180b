"""Monte Carlo consistency of the sensor-based filter on a shortened ``sim:guerreiro-loop``.

20 seeds, 20 s each, true ids (association errors, tested elsewhere, do not confound the
estimator's own consistency).

The consistency test uses ``speed_profile=random``: the forward speed is a seeded random
walk of density 0.02 m/s/sqrt(s) (mean-reverting over 5 s), i.e. the motion the filter's
model describes (Guerreiro et al. eq. (2): body velocity constant up to a random-walk
disturbance). The process noise is then what the simulator does, not a tuning:
sigma_v = [0.02, 0] m/s/sqrt(s) (forward, lateral: the vehicle follows the corridor, so its
lateral body velocity is exactly 0), sigma_p = 0 (landmarks are static and the exact
discretization leaves no Euler error to cover), the paper's bias walk.

The default sinusoidal speed profile (+-30 %, the same for every seed) is a deterministic
acceleration that a random-walk model cannot be consistent on: the second test shows that
the averaged velocity NEES then follows the acceleration (measured, sigma_v 0.02: 75 % of
the steps inside the band over these 20 seeds; with Euler steps no sigma_v in 0.01-0.04 got
above 72 %). On the random profile an isotropic sigma_v = 0.02 (the paper's form) gives
66 %: the lateral NEES is 0.36, conservative, since the true lateral velocity never moves.
"""

from __future__ import annotations

import numpy as np
import pytest

from datasets.simulation.scenarios import load_scenario
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam
from workbench.metrics.consistency import averaged_nees

# a study: the second tier (`pytest -m study`, run by .ci/run after the default tier)
pytestmark = pytest.mark.study

SEEDS = range(20)
DURATION_S = "20"
MATCHED_MODEL = {
    "association": "ids",
    "velocity_walk_m_s_sqrt_s": [0.02, 0.0],
    "landmark_walk_m_sqrt_s": 0.0,
}


def _vehicle_errors(estimate, sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    extras = estimate.diagnostics.extras
    t = extras["vehicle_t"]
    states = extras["vehicle_state"]
    covs = extras["vehicle_covariance"].reshape(len(t), 3, 3)
    truth = sequence.ground_truth
    index = np.searchsorted(truth.body_velocity.t, t - 1e-9)
    true_states = np.hstack(
        [truth.body_velocity.values[index], truth.history.block("gyro_bias").values[index]]
    )
    return t, true_states - states, covs


def _nees(errors: np.ndarray, covs: np.ndarray) -> np.ndarray:
    return np.einsum("ni,ni->n", errors, np.linalg.solve(covs, errors[:, :, None])[:, :, 0])


def _monte_carlo(
    data: dict[str, str], config: dict
) -> tuple[np.ndarray, list, list, list, list, object]:
    vehicle, velocity, bias, nis = [], [], [], []
    for seed in SEEDS:
        sequence = load_scenario(
            "guerreiro-loop", seed, {"duration_s": DURATION_S, "ids": "true", **data}
        )
        estimator = SensorBasedSlam(SensorBasedConfig(**config), sequence)
        for measurement in sequence.measurements():
            estimator.process(measurement)
        estimate = estimator.estimate()
        t, errors, covs = _vehicle_errors(estimate, sequence)
        vehicle.append(_nees(errors, covs))
        velocity.append(_nees(errors[:, :2], covs[:, :2, :2]))
        bias.append(_nees(errors[:, 2:], covs[:, 2:, 2:]))
        nis.append(estimate.diagnostics.nis / estimate.diagnostics.nis_dof)
    return t, vehicle, velocity, bias, nis, sequence


def test_vehicle_nees_inside_the_95_percent_band_when_the_motion_follows_the_model() -> None:
    """Measured: vehicle ANEES 2.41 (band [2.02, 4.16]), inside on 85.1 % of the steps (the
    issue asks >= 80 %); forward/lateral/bias ANEES 0.88/0.66/0.95."""
    _, vehicle, _, bias, nis, _ = _monte_carlo({"speed_profile": "random"}, MATCHED_MODEL)
    vehicle_avg = averaged_nees(np.stack(vehicle), dof=3)
    bias_avg = averaged_nees(np.stack(bias), dof=1)
    assert vehicle_avg.inside_fraction >= 0.8, vehicle_avg.inside_fraction
    assert vehicle_avg.lower <= np.mean(vehicle_avg.mean) <= vehicle_avg.upper
    assert bias_avg.inside_fraction >= 0.8
    assert 0.9 < np.mean(np.concatenate(nis)) < 1.1


def test_deterministic_speed_changes_show_up_as_velocity_nees_following_the_acceleration() -> None:
    """The default profile: the constant-velocity model lags the sinusoidal speed; the
    averaged velocity NEES tracks |acceleration| (the model error, reported, not tuned away)."""
    config = {"association": "ids", "velocity_walk_m_s_sqrt_s": 0.02, "landmark_walk_m_sqrt_s": 0.0}
    t, vehicle, velocity, bias, _, sequence = _monte_carlo({}, config)
    velocity_avg = averaged_nees(np.stack(velocity), dof=2)
    assert averaged_nees(np.stack(bias), dof=1).inside_fraction >= 0.8
    truth = sequence.ground_truth.body_velocity
    acceleration = np.abs(np.gradient(truth.values[:, 0], truth.t))[
        np.searchsorted(truth.t, t - 1e-9)
    ]
    settled = t > 2.0
    correlation = np.corrcoef(acceleration[settled], velocity_avg.mean[settled])[0, 1]
    assert correlation > 0.5
    assert averaged_nees(np.stack(vehicle), dof=3).inside_fraction < 0.8


def _frame_state_pose_nees(
    scenario: str, seeds, data: dict[str, str], config: dict, dof: int
) -> tuple[object, int]:
    """Averaged pose NEES of ``earth_frame_source=filter_state`` runs (the start pose left
    out: it is exact, zero covariance) and how many poses had no truth sample at their stamp."""
    from workbench.metrics.consistency import nees, pose_errors

    runs, unmatched = [], 0
    for seed in seeds:
        sequence = load_scenario(scenario, seed, data)
        estimator = SensorBasedSlam(
            SensorBasedConfig(**config, earth_frame_source="filter_state"), sequence
        )
        for measurement in sequence.measurements():
            estimator.process(measurement)
        pose, truth = estimator.estimate().causal.pose, sequence.ground_truth.pose
        index = np.clip(np.searchsorted(truth.t, pose.t - 1e-9), 0, len(truth.t) - 1)
        matched = np.isclose(truth.t[index], pose.t)
        unmatched += int((~matched).sum())
        kept = np.flatnonzero(matched)[1:]
        runs.append(
            nees(pose_errors(pose.select(kept), truth.select(index[kept])), pose.covariances[kept])
        )
    shortest = min(len(run) for run in runs)
    return averaged_nees(np.stack([run[:shortest] for run in runs]), dof=dof), unmatched


def test_earth_frame_in_the_state_gives_a_consistent_pose() -> None:
    """``earth_frame_source=filter_state`` (the Earth frame as non-visible features,
    ``filters.sensor_based.earth_state``): the pose read back from them, with its first-order
    covariance, is consistent on the matched-model runs above: averaged pose NEES (3 dof)
    inside the 95 % band on most scans (measured: ANEES 2.40 per 3 dof, inside on 99.5 % of
    the scans). The features take no disturbance, so a frame that
    drifted (a wrong sign in eq. (1) for them, a disturbance added) would leave the band."""
    data = {"duration_s": DURATION_S, "ids": "true", "speed_profile": "random"}
    average, unmatched = _frame_state_pose_nees("guerreiro-loop", SEEDS, data, MATCHED_MODEL, 3)
    assert unmatched == 0
    assert average.inside_fraction >= 0.8, average.inside_fraction
    assert average.lower <= np.mean(average.mean) <= average.upper


def test_earth_frame_in_the_state_gives_a_consistent_3d_pose() -> None:
    """The same in 3-D (``sim:aghili-rover``, 10 seeds x 10 s, the scenario's stated
    noise): the derived alignment exports no 3-D covariance (``earth_pose_covariance`` says
    why); the frame's features carry one, and the averaged pose NEES (6 dof) is inside the
    95 % band on most scans (measured: 0.95 per dof, inside on every scan)."""
    average, _ = _frame_state_pose_nees("aghili-rover", range(10), {"duration_s": "10"}, {}, 6)
    assert average.inside_fraction >= 0.8, average.inside_fraction
    assert average.lower <= np.mean(average.mean) <= average.upper
