"""Odometry noise that grows with time, distance and turn: the model, the compounding
Jacobians, and the maximum-likelihood fit (recovering known rates; real UTIAS odometry)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.odometry_calibration import (
    Increments,
    build_windows,
    compose,
    fit_odometry_noise,
    fit_scales,
    speed_factors,
    window_nees,
)
from datasets.odometry_noise import OdometryNoiseModel, read_model_file

TRUE_RATES = np.array(
    [
        [1e-5, 2e-6, 1e-6],  # time
        [4e-4, 1e-4, 2e-5],  # distance
        [1e-4, 0.0, 4e-4],  # turn
    ]
)


def test_variances_add_over_sub_intervals() -> None:
    model = OdometryNoiseModel(TRUE_RATES)
    whole = model.increment_covariance(np.array([1.0, 0.0, 0.2]), 1.0)
    parts = sum(model.increment_covariance(np.array([0.02, 0.0, 0.004]), 0.02) for _ in range(50))
    np.testing.assert_allclose(whole, parts, rtol=1e-12)
    # a velocity sample's covariance integrates to the increment's x and theta variances
    per_sample = model.velocity_covariance(0.5, 0.1, 0.02)
    increment = model.increment_covariance(np.array([0.01, 0.0, 0.002]), 0.02)
    np.testing.assert_allclose(0.02**2 * np.diag(per_sample), increment[[0, 2], [0, 2]])


def test_model_file_round_trip_and_bad_file(tmp_path: Path) -> None:
    import yaml

    model = OdometryNoiseModel(TRUE_RATES, "test")
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump({"odometry_noise": model.as_dict()}))
    np.testing.assert_array_equal(read_model_file(path).rates, TRUE_RATES)
    path.write_text("odometry_noise: {rates: {time: {x: 1}}}")
    with pytest.raises(InputError, match=r"model\.yaml"):
        read_model_file(path)
    with pytest.raises(InputError, match=">= 0"):
        OdometryNoiseModel(-TRUE_RATES)


def test_compounding_jacobians_match_finite_differences() -> None:
    rng = np.random.default_rng(3)
    values = np.column_stack(
        [rng.uniform(0.1, 0.5, 7), rng.normal(0, 0.05, 7), rng.normal(0, 0.3, 7)]
    )
    positions, headings, jacobians = compose(values)
    final = np.array([*positions[-1], headings[-1]])
    step = 1e-7
    for j in range(len(values)):
        for column in range(3):
            moved = values.copy()
            moved[j, column] += step
            p, h, _ = compose(moved)
            numeric = (np.array([*p[-1], h[-1]]) - final) / step
            np.testing.assert_allclose(jacobians[j, :, column], numeric, atol=1e-5)


def _simulated_odometry(seed: int, steps: int = 30000, dt: float = 0.05):
    """Odometry drawn from ``TRUE_RATES`` along a wandering path, and the true poses."""
    rng = np.random.default_rng(seed)
    speed = np.abs(1.0 + 0.5 * np.sin(np.arange(steps) * dt / 7.0))
    rate = 0.4 * np.sin(np.arange(steps) * dt / 3.0) + 0.1 * rng.standard_normal(steps)
    true = np.column_stack([speed * dt, np.zeros(steps), rate * dt])
    variances = OdometryNoiseModel(TRUE_RATES).variances(
        np.full(steps, dt), np.abs(true[:, 0]), true[:, 2]
    )
    measured = true + np.sqrt(variances) * rng.standard_normal((steps, 3))
    positions, headings, _ = compose(true)
    times = np.arange(steps + 1) * dt
    increments = Increments(times[1:], np.full(steps, dt), measured)
    return increments, times, positions, headings


def test_fit_recovers_known_rates_and_whitens_the_windows() -> None:
    increments, times, positions, headings = _simulated_odometry(seed=0)
    windows = build_windows(increments, times, positions, headings, window_s=5.0)
    fit = fit_odometry_noise(windows, "simulated")
    assert len(fit.excluded) == 0
    assert fit.nees_per_dof == pytest.approx(1.0, abs=0.1)
    # Rates of terms that move together (time and distance at a near-constant speed) trade
    # off against each other; what the data determine is the covariance they predict.
    fitted = np.einsum("p,wpij->wij", fit.model.rates.ravel(), windows.bases)
    true = np.einsum("p,wpij->wij", TRUE_RATES.ravel(), windows.bases)
    ratios = np.median(
        np.diagonal(fitted, axis1=1, axis2=2) / np.diagonal(true, axis1=1, axis2=2), axis=0
    )
    np.testing.assert_allclose(ratios, 1.0, atol=0.25)
    # ten times the true noise is visibly conservative, a tenth visibly optimistic
    assert np.mean(window_nees(10 * TRUE_RATES, windows)) / 3 < 0.2
    assert np.mean(window_nees(0.1 * TRUE_RATES, windows)) / 3 > 5.0


def test_scale_fit_recovers_known_speed_turn_and_coupling() -> None:
    """Odometry that overstates the turn by 1/0.94 and the distance by 1/0.97, the more so
    the faster it turns (coupling 0.8 s/rad: UTIAS-like), with the model's noise on top:
    the fit recovers all three, and holds what it is given."""
    increments, times, positions, headings = _simulated_odometry(seed=3)
    commanded_rate = increments.values[:, 2] / 0.94 / increments.dt
    forward = speed_factors(commanded_rate, 0.97, 0.8)
    biased = increments.values / np.column_stack([forward, forward, np.full(len(forward), 0.94)])
    biased_increments = Increments(increments.t_end, increments.dt, biased)
    fit = fit_scales(biased_increments, times, positions, headings, window_s=5.0)
    assert fit.speed == pytest.approx(0.97, abs=0.005)
    assert fit.turn == pytest.approx(0.94, abs=0.003)
    assert fit.coupling == pytest.approx(0.8, abs=0.02)
    assert fit.heading_rms_after_rad < 0.8 * fit.heading_rms_before_rad
    assert fit.position_rms_after_m < 0.5 * fit.position_rms_before_m
    # without the coupling the same data are explained worse
    uncoupled = fit_scales(
        biased_increments, times, positions, headings, window_s=5.0, fixed={"coupling": 0.0}
    )
    assert uncoupled.coupling == 0.0
    assert uncoupled.position_rms_after_m > 2 * fit.position_rms_after_m
    unbiased = fit_scales(increments, times, positions, headings, window_s=5.0)
    assert unbiased.speed == pytest.approx(1.0, abs=0.003)
    assert unbiased.turn == pytest.approx(1.0, abs=0.003)
    assert unbiased.coupling == pytest.approx(0.0, abs=0.01)


def test_a_reference_glitch_is_excluded_and_counted() -> None:
    increments, times, positions, headings = _simulated_odometry(seed=1, steps=12000)
    positions = positions.copy()
    positions[2000:2003] += 3.0  # a Vicon-like jump of metres for three samples
    windows = build_windows(increments, times, positions, headings, window_s=5.0)
    fit = fit_odometry_noise(windows, "simulated")
    assert 1 <= len(fit.excluded) <= 2
    assert np.all(np.abs(fit.excluded - 100.0) <= 5.0)  # the windows around t = 100 s
    assert fit.nees_per_dof == pytest.approx(1.0, abs=0.15)


def test_too_short_a_recording_is_an_input_error() -> None:
    increments, times, positions, headings = _simulated_odometry(seed=2, steps=400)
    with pytest.raises(InputError, match="need at least 10"):
        build_windows(increments, times, positions, headings, window_s=5.0)


@pytest.mark.study
def test_utias_odometry_fitted_against_vicon_is_speed_dependent(utias_folder: Path) -> None:
    from datasets.measurements import Odometry
    from datasets.utias import load

    sequence = load(f"{utias_folder}#robot2", 0, {})
    model = sequence.noise.odometry
    assert model is not None and "Vicon" in model.source
    covariances = [m.covariance for m in sequence.measurements() if isinstance(m, Odometry)]
    # speed- and turn-dependent: the per-sample covariance is not one constant
    assert np.ptp([c[0, 0] for c in covariances]) > 0
    white = load(f"{utias_folder}#robot2", 0, {"odometry_noise": "white"})
    assert white.noise.odometry is None


@pytest.mark.study
def test_utias_odometry_scales_are_fitted_against_vicon_or_given(utias_folder: Path) -> None:
    """The commanded velocities overstate the turn (robot 1: about 6 %) and the speed the
    more the robot turns; the loader fits the calibration at load and says so, or takes it
    as given."""
    from datasets.measurements import Odometry
    from datasets.utias import load

    fitted = load(f"{utias_folder}#robot1", 0, {"duration_s": "20"})
    scales = fitted.metadata["odometry_scales"]
    assert 0.9 < scales["turn"] < 0.98
    assert 0.5 < scales["coupling"] < 1.5  # speed lost while turning (the fit's docstring)
    assert scales["position_rms_after_m"] < 0.7 * scales["position_rms_before_m"]
    assert "Vicon" in scales["source"]
    assert scales["heading_rms_after_deg"] < scales["heading_rms_before_deg"]
    given = load(
        f"{utias_folder}#robot1",
        0,
        {
            "duration_s": "20",
            "odometry_speed_scale": "1",
            "odometry_turn_scale": "1",
            "odometry_speed_turn_coupling": "0",
        },
    )
    assert given.metadata["odometry_scales"] == {
        "speed": 1.0,
        "turn": 1.0,
        "coupling": 0.0,
        "source": "given",
    }
    raw = [m for m in given.measurements() if isinstance(m, Odometry)]
    scaled = [m for m in fitted.measurements() if isinstance(m, Odometry)]
    assert len(raw) == len(scaled)
    moving = next(k for k, m in enumerate(raw) if abs(m.velocity[1]) > 0.1)
    speed, rate = raw[moving].velocity
    factor = scales["speed"] * (1 - scales["coupling"] * abs(rate))
    np.testing.assert_allclose(
        scaled[moving].velocity, [factor * speed, scales["turn"] * rate], rtol=1e-12
    )


@pytest.mark.study
def test_calibrate_noise_command_writes_a_model_the_loader_reads(
    utias_folder: Path, tmp_path: Path, capsys
) -> None:
    from datasets.utias import load
    from workbench.cli import main

    out = tmp_path / "robot3.yaml"
    status = main(["calibrate-noise", f"utias:{utias_folder}#robot3", "--out", str(out)])
    printed = capsys.readouterr().out
    assert status == 0
    assert "fitted against truth" in printed
    import re

    mean = float(re.search(r"NEES per dof on 5 s windows: mean ([0-9.]+)", printed).group(1))
    assert 0.8 < mean < 1.25  # the fitted model whitens the windows it was fitted on
    model = read_model_file(out)
    sequence = load(f"{utias_folder}#robot3", 0, {"odometry_noise": str(out)})
    np.testing.assert_allclose(sequence.noise.odometry.rates, model.rates)


def test_calibrate_noise_on_a_dataset_without_odometry_is_one_clear_error(capsys) -> None:
    from workbench.cli import main

    status = main(["calibrate-noise", "sim:guerreiro-loop", "--data", "duration_s=5"])
    err = capsys.readouterr().err
    assert status == 2 and "no planar odometry" in err
