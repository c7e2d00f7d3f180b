"""Truth quality as data (``datasets.truth_quality``) and scoring that leaves it out.

Simulated truth (the Guerreiro loop, planar, and the Aghili rover's terrain loop, 3-D, both
at 50 Hz) gets every failure the detector names injected at seeded places; every injected
interval must be excluded (up to two samples at its edges) and nothing else. The shared
UTIAS recording (``../shared/data/utias-mrclam1``, skipped when absent) must show only
its known heading glitches across +-pi. The metrics must score nothing inside an excluded
interval nor across a gap of the truth, and stay bit for bit the same without them.
"""

from __future__ import annotations

import io
import math
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from datasets.errors import InputError
from datasets.odometry_calibration import Increments
from datasets.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix, so3_exp, wrap_angle
from datasets.simulation.aghili_rover import ROVER_TERRAIN, ROVER_VIA_POINTS_XY
from datasets.simulation.assembly import sample_times
from datasets.simulation.guerreiro_motion import guerreiro_loop_motion
from datasets.simulation.guerreiro_sensors import relative_pose_odometry
from datasets.simulation.trajectories import TerrainViaPointLoop
from datasets.state import GroundTruth, StateHistory
from datasets.trajectory import Trajectory
from datasets.truth_quality.assess import assess_truth
from datasets.truth_quality.intervals import TruthInterval, TruthKind
from datasets.truth_quality.settings import TruthQualitySettings
from workbench.evo_results import write_evo_results
from workbench.metrics.ate import ate_report
from workbench.metrics.state_errors import pose_error_series
from workbench.metrics.summary import accuracy_metrics, scored_pairs
from workbench.metrics.timestamps import MAX_INTERPOLATION_STEPS, trajectory_at, vectors_at

RATE_HZ = 50.0
STEP_S = 1.0 / RATE_HZ
EDGE_SAMPLES = 2
"""An injected interval counts as found when all of it but this many samples at each edge
is excluded, and as clean when nothing farther than this from it is."""

UTIAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "utias-mrclam1"


# --------------------------------------------------------------------------- truths


@dataclass(frozen=True)
class Truth:
    """A truth stream on a regular grid: times (N,), positions (N, d), headings (N,) or
    quaternions (N, 4), and planar odometry increments (or None)."""

    t: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    odometry: Increments | None


@dataclass(frozen=True)
class Injected:
    """Grid samples ``first..last`` made bad, and the kinds that may report them."""

    first: int
    last: int
    what: str
    kinds: tuple[str, ...]


def planar_truth(seed: int) -> Truth:
    """600 s round the Guerreiro loop at 0.1 m/s (a UTIAS robot's pace) with a seeded
    random speed, at 50 Hz, and wheel odometry between the samples."""
    kinematics = guerreiro_loop_motion(0.1, 0.01, np.random.default_rng(seed)).kinematics(
        sample_times(600.0, RATE_HZ)
    )
    heading = np.arctan2(kinematics.rotation[:, 1, 0], kinematics.rotation[:, 0, 0])
    odometry = relative_pose_odometry(
        kinematics, np.array([3e-4, 3e-4, 5e-4]), 1.0, 1.0, np.random.default_rng([seed, 5])
    )
    return Truth(
        kinematics.t,
        kinematics.position[:, :2].copy(),
        heading,
        Increments(odometry.t, odometry.dt, odometry.increments),
    )


def spatial_truth(seed: int) -> Truth:
    """420 s of the Aghili rover's 3-D terrain loop at 1 m/s, 50 Hz, starting at a seeded
    place on the loop."""
    loop = TerrainViaPointLoop(ROVER_VIA_POINTS_XY, 1.0, ROVER_TERRAIN)
    kinematics = loop.kinematics(sample_times(420.0, RATE_HZ) + 7.0 * seed)
    return Truth(
        kinematics.t, kinematics.position.copy(), quat_wxyz_from_matrix(kinematics.rotation), None
    )


@pytest.fixture(scope="session")
def planar_truths() -> dict[int, Truth]:
    return {seed: planar_truth(seed) for seed in range(3)}


@pytest.fixture(scope="session")
def spatial_truths() -> dict[int, Truth]:
    return {seed: spatial_truth(seed) for seed in range(3)}


def _turned(rotations: np.ndarray, angle_rad: float) -> np.ndarray:
    """Headings or quaternions turned by ``angle_rad`` about the body z axis."""
    if rotations.ndim == 1:
        return np.asarray(wrap_angle(rotations + angle_rad), dtype=float)
    turn = so3_exp(np.array([0.0, 0.0, angle_rad]))
    return quat_wxyz_from_matrix(matrix_from_quat_wxyz(rotations) @ turn)


def inject(truth: Truth, seed: int) -> tuple[np.ndarray, Truth, list[Injected]]:
    """Every failure at a seeded start, 20 s of good truth apart: a 0.5 s and a 3 s dropout,
    10 s at half the rate, a 2 s freeze while moving, a one-sample 0.4 m spike, a
    one-sample pi flip, a 14 s wrong track bounded by steps (offset 0.3 m rising smoothly
    to 2.7 m and back to 0.5-2.7 m, turning by up to 25 degrees), a heading off by 2.15 rad
    for 100 s with 5 cm position steps at its edges, the heading flipped by pi for 5 s,
    and last an isolated 0.5 m step that stays.

    Returns (kept samples of the grid, the injected truth on the full grid, injections).
    """
    rng = np.random.default_rng([seed, 99])
    positions, rotations = truth.positions.copy(), truth.rotations.copy()
    keep = np.ones(len(truth.t), dtype=bool)
    dimension = positions.shape[1]
    second, apart = int(RATE_HZ), int(20 * RATE_HZ)
    at = apart + int(rng.integers(0, 5 * second))
    found: list[Injected] = []

    def direction() -> np.ndarray:
        vector = rng.normal(size=dimension)
        return vector / np.linalg.norm(vector)

    for seconds in (0.5, 3.0):
        count = int(seconds * RATE_HZ)
        keep[at : at + count] = False
        found.append(Injected(at, at + count - 1, f"{seconds} s dropout", ("dropout",)))
        at += count + apart
    count = int(10 * RATE_HZ)
    keep[at + 1 : at + count : 2] = False  # every other sample: 25 Hz
    found.append(Injected(at, at + count, "10 s at half rate", ("rate_change",)))
    at += count + apart
    count = int(2 * RATE_HZ)
    positions[at + 1 : at + count + 1] = positions[at]
    rotations[at + 1 : at + count + 1] = rotations[at]
    found.append(Injected(at + 1, at + count, "2 s freeze", ("freeze",)))
    at += count + apart
    positions[at] += 0.4 * direction()
    found.append(Injected(at, at, "0.4 m spike", ("wrong_track",)))
    at += apart
    rotations[at] = _turned(rotations[at : at + 1], math.pi)[0]
    found.append(Injected(at, at, "pi spike", ("wrong_track",)))
    at += apart
    count = int(14 * RATE_HZ)
    tau = np.linspace(0.0, 1.0, count)
    last = rng.uniform(0.5, 2.7)
    size = np.where(
        tau < 0.5,
        0.3 + 2.4 * np.sin(np.pi * tau) ** 2,
        last + (2.7 - last) * np.sin(np.pi * tau) ** 2,
    )
    angle = rng.uniform(-np.pi, np.pi) + rng.uniform(-0.44, 0.44) * tau
    offset = np.column_stack([np.cos(angle), np.sin(angle), np.full(count, 0.1)])
    positions[at : at + count] += size[:, None] * offset[:, :dimension]
    found.append(Injected(at, at + count - 1, "14 s wrong track", ("wrong_track",)))
    at += count + apart
    count = int(100 * RATE_HZ)
    rotations[at : at + count] = _turned(rotations[at : at + count], 2.15)
    positions[at : at + count] += 0.05 * direction()
    found.append(Injected(at, at + count - 1, "2.15 rad for 100 s", ("wrong_track", "heading")))
    at += count + apart
    count = int(5 * RATE_HZ)
    rotations[at : at + count] = _turned(rotations[at : at + count], math.pi)
    found.append(Injected(at, at + count - 1, "pi for 5 s", ("wrong_track", "heading")))
    at += count + apart
    positions[at + 1 :] += 0.5 * direction()
    found.append(Injected(at, at + 1, "0.5 m step", ("jump",)))
    assert at + 10 * second < len(truth.t), "the injections must fit the trajectory"
    return keep, replace(truth, positions=positions, rotations=rotations), found


def check_found(
    grid_t: np.ndarray, quality, injections: list[Injected], edge: int = EDGE_SAMPLES
) -> list[str]:
    """What is wrong with ``quality`` on the full grid: parts of injections kept, kinds
    not reported, samples excluded away from every injection. Empty: all good."""
    kept = quality.keep_mask(grid_t)
    core = np.zeros(len(grid_t), dtype=bool)
    near = np.zeros(len(grid_t), dtype=bool)
    problems = []
    for injection in injections:
        core[injection.first + edge : injection.last + 1 - edge] = True
        near[max(injection.first - edge, 0) : injection.last + 1 + edge] = True
        missed = (
            core[injection.first : injection.last + 1] & kept[injection.first : injection.last + 1]
        )
        if np.any(missed):
            problems.append(f"{injection.what}: {int(missed.sum())} samples kept")
        start, end = grid_t[injection.first], grid_t[injection.last]
        kinds = {i.kind.value for i in quality.intervals if i.start_s <= end and i.end_s >= start}
        if not kinds & set(injection.kinds):
            problems.append(f"{injection.what} reported as {sorted(kinds)}")
        core[:] = False
    extra = np.flatnonzero(~near & ~kept)
    if len(extra):
        problems.append(
            f"{len(extra)} other samples excluded, the first at {grid_t[extra[0]]:.2f} s"
        )
    return problems


# --------------------------------------------------------------------------- simulated


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("with_odometry", [False, True])
def test_every_injected_failure_of_planar_truth_is_found_and_nothing_else(
    planar_truths, seed, with_odometry
):
    truth = planar_truths[seed]
    keep, bad, injections = inject(truth, seed)
    quality = assess_truth(
        bad.t[keep],
        bad.positions[keep],
        bad.rotations[keep],
        motion=truth.odometry if with_odometry else None,
    )
    assert check_found(truth.t, quality, injections) == []
    assert len(quality.lines()) == len(quality.intervals)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_injected_failure_of_3d_truth_is_found_and_nothing_else(spatial_truths, seed):
    truth = spatial_truths[seed]
    keep, bad, injections = inject(truth, seed)
    quality = assess_truth(bad.t[keep], bad.positions[keep], bad.rotations[keep])
    assert check_found(truth.t, quality, injections) == []
    assert "heading_moving_fraction" not in quality.thresholds  # off by default in 3-D


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clean_simulated_truth_excludes_nothing(planar_truths, spatial_truths, seed):
    planar = planar_truths[seed]
    assert assess_truth(planar.t, planar.positions, planar.rotations).intervals == ()
    with_odometry = assess_truth(
        planar.t, planar.positions, planar.rotations, motion=planar.odometry
    )
    assert with_odometry.intervals == ()
    assert with_odometry.thresholds["motion_windows"] > 500  # the check did run
    assert assess_truth(planar.t, planar.positions).intervals == ()  # positions only
    spatial = spatial_truths[seed]
    assert assess_truth(spatial.t, spatial.positions, spatial.rotations).intervals == ()


@pytest.mark.parametrize("seed", [0, 1])
def test_a_smooth_departure_and_return_is_found_by_the_odometry_only(planar_truths, seed):
    """Offset ramping to 1.5 m over 3 s, held 8 s, ramping back: no step to pair, and a
    constant offset moves exactly as the truth does (without odometry only the ramps can
    be seen, by the heading check). The odometry sees both ramps, which undo each other:
    the whole span is a wrong track, up to one motion window at the edges."""
    truth = planar_truths[seed]
    rng = np.random.default_rng([seed, 7])
    start = int((200 + 6 * seed) * RATE_HZ)
    ramp = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, int(3 * RATE_HZ)))
    profile = np.concatenate([ramp, np.ones(int(8 * RATE_HZ)), ramp[::-1]])
    angle = rng.uniform(-np.pi, np.pi)
    positions = truth.positions.copy()
    positions[start : start + len(profile)] += (
        1.5 * profile[:, None] * np.array([math.cos(angle), math.sin(angle)])
    )
    smooth = [Injected(start, start + len(profile) - 1, "smooth 1.5 m", ("wrong_track",))]
    window = TruthQualitySettings().motion_window_steps
    with_odometry = assess_truth(truth.t, positions, truth.rotations, motion=truth.odometry)
    assert check_found(truth.t, with_odometry, smooth, edge=window) == []


def test_positions_only_truth_finds_dropouts_spikes_and_wrong_tracks(planar_truths):
    truth = planar_truths[0]
    positions, keep = truth.positions.copy(), np.ones(len(truth.t), dtype=bool)
    keep[3000:3100] = False
    positions[5000] += [0.3, -0.2]
    positions[8000:8700] += [0.6, 0.9]
    quality = assess_truth(truth.t[keep], positions[keep])
    injected = [
        Injected(3000, 3099, "dropout", ("dropout",)),
        Injected(5000, 5000, "spike", ("wrong_track",)),
        Injected(8000, 8699, "wrong track", ("wrong_track",)),
    ]
    assert check_found(truth.t, quality, injected) == []


def test_a_freeze_is_a_held_value_while_moving_not_a_vehicle_standing_still():
    t = np.arange(2000) * STEP_S
    speed = np.where((t > 10) & (t < 20), 0.0, 0.2)  # stands still for 10 s
    x = np.cumsum(speed) * STEP_S
    positions = np.column_stack([x, np.zeros_like(x)])
    assert assess_truth(t, positions, np.zeros_like(t)).intervals == ()


def test_a_faster_segment_and_a_freeze_to_the_end_are_found():
    """1 m/s along x at 50 Hz for 60 s, sampled at 100 Hz from 20 s to 30 s, and the last
    2 s holding the value of 58 s."""
    t = np.arange(3001) * STEP_S
    t = np.sort(np.concatenate([t, t[1000:1500] + 0.5 * STEP_S]))
    positions = np.column_stack([t, np.zeros_like(t)])
    held = t > 58.0
    positions[held] = positions[np.flatnonzero(held)[0] - 1]
    quality = assess_truth(t, positions, np.zeros_like(t))
    kinds = [(i.kind, round(i.start_s, 2), round(i.end_s, 2)) for i in quality.intervals]
    assert kinds == [(TruthKind.RATE_CHANGE, 20.0, 30.0), (TruthKind.FREEZE, 58.02, 60.0)]


def test_times_that_do_not_increase_are_refused():
    t = np.array([0.0, 0.1, 0.1, 0.3])
    with pytest.raises(InputError, match="must increase"):
        assess_truth(t, np.zeros((4, 2)), np.zeros(4))
    with pytest.raises(InputError, match="rotations"):
        assess_truth(t[:3] * 0 + [0, 1, 2], np.zeros((3, 2)), np.zeros((3, 3)))


# --------------------------------------------------------------------------- UTIAS


@pytest.fixture(scope="session")
def utias_quality():
    """Every robot of the shared UTIAS recording: (times, headings, TruthQuality with the
    odometry as motion). Row index x 0.02 s is the time (this copy is resampled to 0.02 s
    and its time column rounded after 1000 s), as the loader does."""
    if not UTIAS.is_dir():
        pytest.skip(f"UTIAS MRCLAM data absent (expected at {UTIAS})")
    from datasets.utias import read_table

    found = {}
    for robot in range(1, 6):
        truth = read_table(UTIAS / f"Robot{robot}_Groundtruth.dat", ("t", "x", "y", "h")).values
        odometry = read_table(UTIAS / f"Robot{robot}_Odometry.dat", ("t", "v", "w")).values
        t = np.arange(len(truth)) * 0.02
        odo_t = np.arange(len(odometry)) * 0.02
        dt = np.diff(odo_t)
        # the row at t drives the interval ending at t (the loader's convention)
        increments = Increments(
            odo_t[1:],
            dt,
            np.column_stack([odometry[1:, 1] * dt, np.zeros(len(dt)), odometry[1:, 2] * dt]),
        )
        quality = assess_truth(t, truth[:, 1:3], truth[:, 3], motion=increments)
        found[robot] = (t, truth[:, 3], quality)
    return found


@pytest.mark.parametrize("robot", [1, 2, 3, 4, 5])
def test_utias_truth_shows_only_its_heading_glitches_across_pi(utias_quality, robot):
    """Dataset 1's known quirk: the resampling interpolated some headings the long way
    round where they cross +-pi (runs of 1-5 samples). The detector finds them (every
    robot has some) as short excursions that return, between good samples within 0.2 rad
    of +-pi that differ by less than 0.2 rad the short way; nothing else, and well under
    0.1 % of the recording. The odometry (commanded velocities) contradicts no window."""
    t, heading, quality = utias_quality[robot]
    assert len(quality.intervals) >= 5
    assert {interval.kind for interval in quality.intervals} == {TruthKind.WRONG_TRACK}
    excluded = ~quality.keep_mask(t)
    assert excluded.sum() < 0.001 * len(t)
    assert quality.thresholds["motion_windows"] > 0.9 * len(t) / 50
    for interval in quality.intervals:
        first = int(round(interval.start_s / 0.02))
        last = int(round(interval.end_s / 0.02))
        assert last - first + 1 <= 5, interval.line()
        before, after = heading[first - 1], heading[last + 1]
        assert min(abs(before), abs(after)) > math.pi - 0.2, interval.line()
        assert abs(wrap_angle(after - before)) < 0.2, interval.line()


# --------------------------------------------------------------------------- metrics


def _truth_and_estimate(excluded: tuple[TruthInterval, ...]) -> tuple[GroundTruth, Trajectory]:
    """A planar truth at 10 Hz for 60 s on a circle, with a 3 s gap (samples removed) from
    40 s and its samples from 20 s to 25 s pushed 1 m off; the estimate is the true circle
    at 10 Hz (so it agrees with the truth wherever the truth is right) plus a small seeded
    error, with planar covariances."""
    t = np.round(np.arange(601) * 0.1, 9)
    angle = 0.1 * t
    positions = 5.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    heading = np.asarray(wrap_angle(angle + np.pi / 2), dtype=float)
    rng = np.random.default_rng(3)
    estimate = Trajectory(
        t.copy(),
        positions + rng.normal(scale=0.02, size=positions.shape),
        np.asarray(wrap_angle(heading + rng.normal(scale=0.01, size=len(t))), dtype=float),
        np.tile(np.diag([4e-4, 4e-4, 1e-4]), (len(t), 1, 1)),
    )
    wrong = positions.copy()
    wrong[(t >= 20.0) & (t <= 25.0)] += [1.0, 0.0]
    kept = ~((t > 40.0) & (t < 43.0))
    truth = Trajectory(t[kept], wrong[kept], heading[kept])
    return GroundTruth(history=StateHistory(pose=truth), excluded=excluded), estimate


EXCLUDED = (TruthInterval(20.0, 25.0, TruthKind.WRONG_TRACK, "test: 1 m off"),)


def test_an_excluded_interval_and_a_gap_are_not_scored(tmp_path):
    truth, estimate = _truth_and_estimate(EXCLUDED)
    ignorant, _ = _truth_and_estimate(())
    inside_excluded = (estimate.t >= 20.0) & (estimate.t <= 25.0)
    in_gap = (estimate.t > 40.0) & (estimate.t < 43.0)

    # NEES / pose errors: the truth is looked up at every estimate time except those
    found = pose_error_series(estimate, truth)
    assert found is not None
    assert np.array_equal(found[2], ~inside_excluded & ~in_gap)
    # without the exclusion the wrong samples are scored (1 m errors); the gap never is
    scored = pose_error_series(estimate, ignorant)
    assert np.array_equal(scored[2], ~in_gap)
    assert np.max(np.abs(scored[1][:, :2])) > 0.9

    # ATE by nearest stamp: the excluded estimate poses leave the pairs (the gap has no
    # truth samples to pair with anyway), so the pair count drops by exactly them
    pairs = scored_pairs(estimate, truth)
    assert pairs is not None
    assert write_evo_results(tmp_path, pairs, "excluded")
    with zipfile.ZipFile(tmp_path / "ape.zip") as archive:
        ape = np.load(io.BytesIO(archive.read("error_array.npy")))
    with zipfile.ZipFile(tmp_path / "rpe.zip") as archive:
        rpe = np.load(io.BytesIO(archive.read("error_array.npy")))
    pairs_without = ate_report(truth.pose, estimate, align="se2")["pairs"]
    assert len(ape) == int(np.sum(~inside_excluded & ~in_gap))
    assert pairs_without - len(ape) == int(np.sum(inside_excluded))
    assert np.max(ape) < 0.1  # the 1 m wrong truth is not in the errors
    # RPE over consecutive pairs: the pair across the excluded interval is dropped
    assert len(rpe) == len(ape) - 2

    metrics = accuracy_metrics(estimate, truth)
    assert metrics["ate_rmse_m"] == pytest.approx(math.sqrt(np.mean(ape**2)), rel=1e-12)
    assert metrics["ate_rmse_m"] < 0.05
    assert accuracy_metrics(estimate, ignorant)["ate_rmse_m"] > 0.2


def test_without_exclusions_the_numbers_are_evos():
    truth, estimate = _truth_and_estimate(())
    metrics = accuracy_metrics(estimate, truth)
    assert metrics["ate_rmse_m"] == ate_report(truth.pose, estimate, align="se2")["rmse_m"]
    assert metrics["ate_rmse_raw_m"] == ate_report(truth.pose, estimate, align="none")["rmse_m"]


def test_truth_is_interpolated_across_small_steps_only():
    # median step 1 s; gaps of MAX_INTERPOLATION_STEPS (4) and of 5 steps
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 8.0, 13.0, 14.0, 15.0])
    assert MAX_INTERPOLATION_STEPS == 4.0
    values = (10.0 * t)[:, None]
    queries = np.array([0.5, 6.0, 8.0, 10.0, 13.0, 14.5])
    found, valid = vectors_at(t, values, queries)
    # the gap of 4 steps is bridged; the one of 5 is not, except at its sampled ends
    assert valid.tolist() == [True, True, True, False, True, True]
    assert found[:, 0].tolist() == pytest.approx([5.0, 60.0, 80.0, 130.0, 145.0])
    assert vectors_at(t, values, queries, max_gap_s=math.inf)[1].all()
    pose = Trajectory(t, np.column_stack([t, t]), np.zeros(len(t)))
    excluded = (TruthInterval(2.0, 2.0, TruthKind.JUMP, "test"),)
    _, valid = trajectory_at(pose, np.array([1.5, 2.0, 2.5, 3.0]), excluded)
    # 2.0 is excluded, and so is everything interpolated from it
    assert valid.tolist() == [False, False, False, True]
    assert MAX_INTERPOLATION_STEPS == TruthQualitySettings().dropout_min_steps


def test_ground_truth_says_which_times_it_trusts():
    truth = GroundTruth(history=StateHistory(), excluded=EXCLUDED)
    assert truth.trusted(np.array([19.9, 20.0, 22.0, 25.0, 25.1])).tolist() == [
        True,
        False,
        False,
        False,
        True,
    ]
    assert GroundTruth(history=StateHistory()).trusted(np.array([1.0])).tolist() == [True]
