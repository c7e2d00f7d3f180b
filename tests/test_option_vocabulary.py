"""One option vocabulary (issue 39): one name per idea across every registered estimator,
its unit in the name, one meaning and default per name unless the estimator says why; the
old names still load (``--set``, ``--config``, an old run folder's ``config.yaml``) with one
warning line. The same across the two corner extractors' options (the 3-D lidar's
``CornerConfig``, the 2-D laser's ``Laser2dCornerSettings``): a name they share means one
thing, its two defaults each with the sensor's reason, and no idea has two names."""

from __future__ import annotations

import types
import typing
from collections import defaultdict

import numpy as np
import pytest
import yaml
from pydantic.fields import FieldInfo

from datasets.errors import InputError
from datasets.estimator_options import ESTIMATOR_NOTE
from datasets.laser2d.corners import Laser2dCornerSettings
from datasets.laser2d.frontend import Laser2dFrontEndSettings
from datasets.lidar.corner_config import SENSOR_NOTE, SHARED_MEANINGS, CornerConfig
from datasets.lidar.frontend_settings import LidarSourceOptions
from datasets.option_renames import RENAMED
from workbench import runner
from workbench.registry import ESTIMATORS, estimator_entry
from workbench.runner import resolve_config

SYNONYMS: dict[str, tuple[str, ...]] = {
    # one idea, its one name now -> the spellings it had
    "velocity_walk_m_s_sqrt_s": (
        "gyro_velocity_sigma_m_s2",
        "sigma_velocity_m_s",
        "acceleration_density",
        "planar_velocity_walk_m_s2",
    ),
    "interval_rate": ("rate_interpolation", "gyro_interval_rate", "imu_interpolation"),
    "gyro_noise_density_rad_s_sqrt_hz": ("gyro_noise_density", "planar_gyro_density"),
    "gyro_bias_walk_rad_s_sqrt_s": ("gyro_bias_walk", "sigma_gyro_bias_rad_s"),
    "landmark_field_of_view_deg": ("field_of_view_deg", "fov_deg"),
    "max_gap_s": ("max_imu_gap_s",),
    "use_odometry": ("motion_input",),
    "initial_position_sigma_m": ("position_sigma_m",),
    "initial_rotation_sigma_rad": ("rotation_sigma_rad",),
    "initial_velocity_sigma_m_s": ("velocity_sigma_m_s",),
    "initial_gyro_bias_sigma_rad_s": ("gyro_bias_sigma_rad_s",),
    "initial_accel_bias_sigma_m_s2": ("accel_bias_sigma_m_s2",),
    # a measurement noise and a process noise: two ideas, two names that say which
    "landmark_measurement_sigma_m": ("landmark_sigma_m",),
    "landmark_walk_m_sqrt_s": ("sigma_landmark_m",),
    "direction_walk_per_sqrt_s": ("sigma_direction",),
    # a landmark on probation: removed unless sighted again soon
    "probation_s": ("prune_single_sightings_after_s",),
}

UNIT_SUFFIXES = (
    "_m",
    "_s",
    "_rad",
    "_deg",
    "_hz",
    "_m_s",
    "_rad_s",
    "_m_s2",
    "_m_sqrt_s",
    "_m_s_sqrt_s",
    "_rad_s_sqrt_s",
    "_rad_s_sqrt_hz",
    "_per_sqrt_s",
)
DIMENSIONLESS_WORDS = ("probability", "scale")
"""A float whose name holds one of these has no unit (a probability, a multiplier)."""
DIMENSIONLESS = {
    "relinearize_threshold": "GTSAM's threshold on a tangent-space step (mixed units)",
    "hypothesis_log_window": "a difference of natural-log likelihoods",
    "new_landmark_density": "1/m^d: its unit depends on the dimension (said in its description)",
}


def _fields() -> dict[str, list[tuple[str, FieldInfo]]]:
    """Field name -> (estimator, field) of every registered estimator's config."""
    found: dict[str, list[tuple[str, FieldInfo]]] = defaultdict(list)
    for entry in ESTIMATORS:
        for name, info in entry.load().Config.model_fields.items():
            found[name].append((entry.name, info))
    return found


def _base(description: str | None) -> str:
    return (description or "").split(ESTIMATOR_NOTE)[0]


def test_one_name_has_one_meaning_unit_and_default():
    problems = []
    for name, uses in _fields().items():
        if len({str(info.annotation) for _, info in uses}) > 1:
            problems.append(f"{name}: types {sorted({str(i.annotation) for _, i in uses})}")
        if len({_base(info.description) for _, info in uses}) > 1:
            problems.append(f"{name}: descriptions differ across {[e for e, _ in uses]}")
        plain = [(e, info) for e, info in uses if ESTIMATOR_NOTE not in (info.description or "")]
        if len({repr(info.default) for _, info in plain}) > 1:
            problems.append(
                f"{name}: defaults {[(e, info.default) for e, info in plain]} without a "
                "stated reason (datasets.estimator_options.for_estimator)"
            )
    assert not problems, "\n".join(problems)


def test_no_idea_is_spelt_two_ways():
    names = set(_fields())
    spelt = {old: new for new, olds in SYNONYMS.items() for old in olds}
    assert not names & set(spelt), f"old spellings still in a config: {sorted(names & set(spelt))}"
    assert not [name for name in names if name.startswith("sigma_")], "sigma_X: spell it X_sigma"
    # every old spelling still loads, as its one new name
    assert {entry.old: entry.new for entry in RENAMED if entry.old in spelt} == {
        old: new for old, new in spelt.items() if old != "fov_deg"
    }


def _floats(annotation: object) -> bool:
    if annotation is float:
        return True
    return any(_floats(arg) for arg in typing.get_args(annotation))


def test_a_physical_quantity_has_its_unit_in_the_name():
    missing = [
        name
        for name, uses in _fields().items()
        if _floats(uses[0][1].annotation)
        and not name.endswith(UNIT_SUFFIXES)
        and not any(word in name for word in DIMENSIONLESS_WORDS)
        and name not in DIMENSIONLESS
    ]
    assert not missing, f"float options without a unit suffix: {missing}"


def _kinds(annotation: object) -> set[object]:
    """The leaf types of an annotation (a Literal counts as one: a choice)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        return {typing.Literal}
    if origin in (typing.Union, types.UnionType, typing.Annotated):
        return set().union(*(_kinds(arg) for arg in typing.get_args(annotation)))
    return {origin or annotation}


def test_the_rest_are_bools_counts_and_choices():
    """What has no float is dimensionless: a switch, a count or a choice of words."""
    for name, uses in _fields().items():
        annotation = uses[0][1].annotation
        if not _floats(annotation):
            kinds = _kinds(annotation)
            assert kinds <= {bool, int, list, types.NoneType, typing.Literal}, (name, kinds)


CORNER_CONFIGS = {"3-D lidar": CornerConfig, "2-D laser": Laser2dCornerSettings}
"""The corner extractors' options: ``--data corner.KEY`` of ``scans:`` and a point-cloud
``bag:`` (3-D), of ``carmen:`` and, as ``laser.corner.KEY``, of a LaserScan ``bag:`` (2-D)."""
CORNER_DIMENSIONLESS_WORDS = ("ratio", "scale")
CONVERTED = {
    # a 2-D option -> the extractor fields it sets through a conversion (another idea, so
    # another name), and the conversion
    "range_sigma_m": {"break_distance_m": "3 sigma_r, the adaptive breakpoint's noise margin"},
    "breakpoint_angle_deg": {"break_range_ratio": "Borges-Aldon: sin(dphi) / sin(lambda - dphi)"},
    "max_missing_beams": {"max_gap_bins": "one bin per beam; more than this many: this + 1"},
}


def test_the_corner_data_keys_are_these_configs():
    assert LidarSourceOptions.model_fields["corner"].annotation is CornerConfig
    assert Laser2dFrontEndSettings.model_fields["corner"].annotation is Laser2dCornerSettings


def test_a_corner_option_name_has_one_meaning_and_each_default_its_reason():
    lidar, laser = (model.model_fields for model in CORNER_CONFIGS.values())
    shared = sorted(set(lidar) & set(laser))
    assert shared == sorted(SHARED_MEANINGS), "a shared name without one shared meaning"
    problems = []
    for name in shared:
        uses = {config: model.model_fields[name] for config, model in CORNER_CONFIGS.items()}
        if len({str(info.annotation) for info in uses.values()}) > 1:
            problems.append(f"{name}: types differ")
        for config, info in uses.items():
            if info.description.split(SENSOR_NOTE)[0] != SHARED_MEANINGS[name]:
                problems.append(f"{name}: the {config} description is not the shared meaning")
        if len({repr(info.default) for info in uses.values()}) > 1:
            problems += [
                f"{name}: the {config} default {info.default} without its reason"
                for config, info in uses.items()
                if SENSOR_NOTE not in info.description
            ]
    assert not problems, "\n".join(problems)


def test_no_corner_idea_is_spelt_two_ways():
    """By description: two names with one meaning (within or across the configs)."""
    names_by_meaning = defaultdict(set)
    for model in CORNER_CONFIGS.values():
        for name, info in model.model_fields.items():
            names_by_meaning[(info.description or "").split(SENSOR_NOTE)[0]].add(name)
    assert not [names for names in names_by_meaning.values() if len(names) > 1]


def _changed(value):
    return value + 1 if isinstance(value, int) and not isinstance(value, bool) else value * 1.25


def test_each_2d_corner_option_reaches_the_extractor_under_its_own_name():
    """By what the 2-D front end does with each option (``corner_config``): an option taken
    as it is goes to the extractor's field of its own name (a shared name means one thing,
    and one idea is not renamed on the way); any other field it sets is a conversion listed
    in ``CONVERTED``."""
    step = np.deg2rad(1.0)
    base = Laser2dCornerSettings()
    before = base.corner_config(step).model_dump()
    problems, converted = [], defaultdict(set)
    for name in Laser2dCornerSettings.model_fields:
        value = _changed(getattr(base, name))
        after = Laser2dCornerSettings(**{name: value}).corner_config(step).model_dump()
        for field, new in after.items():
            if new == before[field]:
                continue
            if field == name and new == value:
                continue
            if field in CONVERTED.get(name, {}) and new != value:
                converted[name].add(field)
                continue
            problems.append(f"2-D {name}={value} sets the extractor's {field}={new}")
        if name in CornerConfig.model_fields and after[name] != value:
            problems.append(f"2-D {name} does not reach the extractor's {name} as it is")
    assert not problems, "\n".join(problems)
    assert converted == {name: set(fields) for name, fields in CONVERTED.items()}


def test_a_corner_quantity_has_its_unit_in_the_name():
    missing = [
        name
        for model in CORNER_CONFIGS.values()
        for name, info in model.model_fields.items()
        if _floats(info.annotation)
        and not name.endswith(UNIT_SUFFIXES)
        and not any(word in name for word in CORNER_DIMENSIONLESS_WORDS)
    ]
    assert not missing, f"float corner options without a unit suffix: {missing}"


@pytest.fixture
def warnings_again(monkeypatch):
    """Each test sees the warnings that the process may already have printed."""
    monkeypatch.setattr(runner, "_warned", set())


def test_an_old_name_in_set_gives_the_new_field_and_one_warning(warnings_again, capsys):
    ekf = estimator_entry("ekf-slam").load()
    config = resolve_config(
        ekf, None, {"acceleration_density": "[0.02, 0.005]", "motion_input": "gyro"}, "ekf-slam"
    )
    assert config.velocity_walk_m_s_sqrt_s == [0.02, 0.005] and config.use_odometry is False
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        "warning: ekf-slam option 'acceleration_density' is now 'velocity_walk_m_s_sqrt_s'",
        "warning: ekf-slam option 'motion_input' is now 'use_odometry' "
        "(motion_input=gyro: use_odometry=false)",
    ]
    resolve_config(ekf, None, {"acceleration_density": "0.1"}, "ekf-slam")
    assert capsys.readouterr().err == ""  # once per process: a sweep resolves it per run


def test_an_old_and_a_new_name_for_one_option_disagreeing_is_an_error():
    ekf = estimator_entry("ekf-slam").load()
    with pytest.raises(InputError, match="'acceleration_density' and 'velocity_walk_m_s_sqrt_s'"):
        resolve_config(
            ekf, None, {"acceleration_density": "0.1", "velocity_walk_m_s_sqrt_s": "0.2"}
        )


def test_an_old_name_of_another_estimator_stays_an_unknown_key():
    dead_reckoning = estimator_entry("dead-reckoning").load()
    with pytest.raises(InputError, match="rate_interpolation: Extra inputs are not permitted"):
        resolve_config(dead_reckoning, None, {"rate_interpolation": "hold"}, "dead-reckoning")


OLD_RUN_CONFIGS = {
    # the config: of run folders written before issue 39 (workbench run, default options)
    "sensor-based": """
      association: auto
      association_window_s: 20.0
      direction_sigma_rad: 0.03490658503988659
      discretization: exact
      earth_frame: true
      field_of_view_deg: null
      gate_probability: 0.99
      gyro_noise_density: null
      id_gate_probability: 0.9999
      in_view_range_m: 5.0
      initial_gyro_bias_rad_s: null
      initial_gyro_bias_sigma_rad_s: null
      initial_velocity_error_m_s: null
      initial_velocity_sigma_m_s: null
      loop_closing: true
      loop_every_s: 2.0
      loop_max_old_sigma_m: 1.5
      loop_min_pairs: 5
      loop_old_after_s: 60.0
      loop_unambiguous_only: true
      max_gap_s: 60.0
      max_jcbb_nodes: 2000
      max_landmarks: 200
      max_missed_in_view: 100
      max_step_s: 0.05
      min_observations: 3
      new_landmark_probability: 0.9999
      odometry_lateral_sigma_m_s: 0.05
      probation_s: 3.0
      rate_interpolation: average
      sigma_direction: 0.01
      sigma_gyro_bias_rad_s: 9.94837673636768e-07
      sigma_landmark_m: null
      sigma_velocity_m_s: 0.1
      snapshot_interval_s: 5.0
      tuning: stated
      use_directions: false
      use_odometry: null
    """,
    "smoother-isam2": """
      accel_bias_sigma_m_s2: null
      anchor_sigma_m: 0.001
      anchors: null
      association: auto
      causal_covariances: true
      extra_iterations: 0
      factorization: CHOLESKY
      gate_probability: 0.99
      gravity_m_s2: null
      gyro_bias_sigma_rad_s: null
      id_gate_probability: 0.9999
      imu_interpolation: true
      innovation_nis: true
      keyframe_imu_stride: null
      landmark_factor: bearing-range
      max_imu_gap_s: 0.5
      max_jcbb_nodes: 2000
      measurement_noise_scale: 1.0
      new_landmark_probability: 0.9999
      odometry_lateral_sigma_m_s: 0.02
      planar_gyro_density: null
      planar_velocity_walk_m_s2: 0.1
      position_sigma_m: null
      relinearize_skip: 1
      relinearize_threshold: 0.05
      rotation_sigma_rad: null
      snapshot_interval_s: 5.0
      use_gps: true
      use_odometry: true
      velocity_sigma_m_s: null
    """,
    "ekf-slam": """
      acceleration_density: 0.3
      association: auto
      estimate_gyro_bias: true
      gap_rate_rad_s: 0.2
      gap_speed_m_s: 0.5
      gate_probability: 0.99
      gyro_bias_sigma_rad_s: null
      gyro_bias_walk: null
      gyro_interval_rate: average
      gyro_noise_density: null
      id_gate_probability: 0.9999
      jacobians: observability-constrained
      max_gap_s: 1.0
      max_jcbb_nodes: 2000
      measurement_noise_scale: 1.0
      motion_input: auto
      new_landmark_probability: 0.9999
      odometry_noise_scale: 1.0
      prune_single_sightings_after_s: null
      rotate_velocity_with_gyro: true
      snapshot_interval_s: 5.0
    """,
    "dead-reckoning": """
      gyro_velocity_sigma_m_s2: 0.05
      max_gap_s: 1.0
    """,
    "aghili": """
      anchors: 3
      initial_gyro_bias_sigma_rad_s: null
      landmark_sigma_m: 0.02
      max_gap_s: 1.0
    """,
}


@pytest.mark.parametrize("estimator", sorted(OLD_RUN_CONFIGS))
def test_an_old_run_folders_config_yaml_loads_under_the_new_names(
    estimator, tmp_path, warnings_again, capsys
):
    old = yaml.safe_load(OLD_RUN_CONFIGS[estimator])
    path = tmp_path / "config.yaml"
    path.write_text(
        yaml.safe_dump({"estimator": estimator, "dataset": "sim:circle", "seed": 1, "config": old})
    )
    config = resolve_config(estimator_entry(estimator).load(), path, None, estimator)
    new_name = {entry.old: entry for entry in RENAMED}
    err = capsys.readouterr().err
    for key, value in old.items():
        entry = new_name.get(key)
        if entry is None or key in type(config).model_fields:
            assert getattr(config, key) == (True if key == "use_odometry" else value)
            continue
        expected = entry.convert(value) if entry.convert else value
        assert getattr(config, entry.new) == expected, key
        assert f"warning: {estimator} option '{key}' is now '{entry.new}'" in err
    assert len(err.splitlines()) == sum(
        key in new_name and key not in type(config).model_fields for key in old
    )


def test_workbench_run_prints_the_warning_of_an_old_name_in_set(tmp_path, warnings_again, capsys):
    """The options are resolved (and the warning printed) before the data is read: a
    missing folder keeps the test fast."""
    from workbench.cli import main

    argv = ["run", "dead-reckoning", f"utias:{tmp_path / 'none'}#robot1", "--no-plots"]
    argv += ["--set", "gyro_velocity_sigma_m_s2=0.2", "--out", str(tmp_path / "run")]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (
        "warning: dead-reckoning option 'gyro_velocity_sigma_m_s2' is now "
        "'velocity_walk_m_s_sqrt_s'"
    )
    assert err[1].startswith("error: ")


def test_a_gap_policy_an_estimator_does_not_implement_is_an_error():
    dead_reckoning = estimator_entry("dead-reckoning").load()
    with pytest.raises(InputError, match="gap_policy: Value error, 'inflate' is not implemented"):
        resolve_config(dead_reckoning, None, {"gap_policy": "inflate"}, "dead-reckoning")


@pytest.fixture(scope="module")
def gapped_loop():
    """2 s of the gyro-only loop with the gyro silent for 1.5 s."""
    from dataclasses import replace

    from datasets.measurements import GyroSample
    from workbench.registry import load_dataset

    sequence = load_dataset("sim:guerreiro-loop", 0, {"duration_s": "3"})
    kept = [
        m for m in sequence.measurements() if not (isinstance(m, GyroSample) and 0.5 < m.t < 2.0)
    ]
    return replace(sequence, stream=lambda: iter(kept))


def _run(name, sequence, **options):
    from workbench.runner import run_estimator

    estimator_class = estimator_entry(name).load()
    config = resolve_config(estimator_class, None, {k: str(v) for k, v in options.items()})
    return run_estimator(estimator_class, config, sequence)


def test_ekf_slam_inflates_a_gap_or_raises_as_its_gap_policy_says(gapped_loop):
    inflated = _run("ekf-slam", gapped_loop)
    assert any(event.kind == "motion_gap" for event in inflated.diagnostics.events)
    with pytest.raises(InputError, match=r"gap of 1\.\d+ s .* \(gap_policy=raise\)"):
        _run("ekf-slam", gapped_loop, gap_policy="raise")


@pytest.mark.parametrize("name", ["ekf-slam", "sensor-based"])
def test_every_interval_rate_runs_and_each_integrates_its_own_way(name, gapped_loop):
    headings = {
        rate: _run(name, gapped_loop, interval_rate=rate, max_gap_s=2).causal.pose.rotations[-1]
        for rate in ("average", "hold", "latest")
    }
    assert len({float(np.ravel(h)[0]) for h in headings.values()}) == 3
