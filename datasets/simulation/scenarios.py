"""Named, seeded simulation scenarios: ``sim:aghili-rover``, ``sim:guerreiro-loop``,
``sim:circle``, ``sim:static``, ``sim:laser2d``: the registry of their option models and
builders, and the loader the workbench registry names.

``load_scenario(argument, seed, options)`` is the dataset loader the registry names.
In the 3-D scenarios the world layout (landmark positions, per-landmark sigmas) comes
from the ``layout_seed`` option (default 0); the corridor building of ``guerreiro-loop`` is
fixed. The sensor noise comes from ``seed``: Monte Carlo runs over seeds see the same world
with fresh noise. Independent generators per sensor mean that
changing one sensor's option does not change another sensor's noise.

Each scenario lives in its own module (``aghili_rover``, ``guerreiro_loop``,
``basic_scenarios`` for ``circle`` and ``static``, ``datasets.laser2d.simulation``), on
shared parts in ``scenario_common`` (options, seeds, noise scale) and ``spatial_scenario``
(the 3-D scenarios). Import a scenario's options
and builder from its module; this one owns the registry (``load_scenario``,
``describe_scenarios``, ``SCENARIO_NAMES``).
"""

from __future__ import annotations

from collections.abc import Callable

from pydantic import BaseModel

from datasets.errors import InputError, did_you_mean
from datasets.laser2d.simulation import Laser2dScenarioOptions, laser2d_scenario
from datasets.options import describe_model, parse_options
from datasets.sequence import Sequence
from datasets.simulation.aghili_rover import (
    AghiliRoverOptions,
    aghili_rover,
)
from datasets.simulation.basic_scenarios import CircleOptions, StaticOptions, circle, static
from datasets.simulation.guerreiro_loop import (
    GuerreiroLoopOptions,
    guerreiro_loop,
)

_SCENARIOS: dict[str, tuple[type[BaseModel], Callable[[int, BaseModel], Sequence], str]] = {
    "aghili-rover": (
        AghiliRoverOptions,
        aghili_rover,
        "Aghili sec. 5: 3-D rover loop through 7 via points on a 30x60 m sloped terrain, 1 m/s, IMU 20 Hz, landmarks 10 Hz, one lap 144 s",
    ),
    "guerreiro-loop": (
        GuerreiroLoopOptions,
        guerreiro_loop,
        "Guerreiro sec. V: 2-D 60 m corridor loop at 0.4 m/s (150 s), 76 wall corners, laser 10 Hz with line of sight, rate gyro 10 Hz",
    ),
    "circle": (
        CircleOptions,
        circle,
        "3-D level circle, r 10 m at 2 m/s, IMU 100 Hz + landmarks, 60 s",
    ),
    "static": (StaticOptions, static, "3-D vehicle at rest (tilted), IMU 100 Hz + landmarks, 60 s"),
    "laser2d": (
        Laser2dScenarioOptions,
        laser2d_scenario,
        "2-D laser scans (181 beams, 5 Hz) ray-cast in the guerreiro-loop building, odometry, corners by the CARMEN front end (datasets.laser2d), no ids",
    ),
}

SCENARIO_NAMES: tuple[str, ...] = tuple(_SCENARIOS)


def load_scenario(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """Simulate scenario ``argument`` with noise ``seed`` and ``--data`` options."""
    if argument not in _SCENARIOS:
        raise InputError(
            f"unknown simulation scenario '{argument}'{did_you_mean(argument, list(_SCENARIOS))} "
            f"(known: {', '.join(_SCENARIOS)})"
        )
    model, simulate, _ = _SCENARIOS[argument]
    parsed = parse_options(model, options, f"sim:{argument} --data")
    return simulate(int(seed), parsed)


def describe_scenarios() -> list[str]:
    """Lines for ``workbench list --verbose``: each scenario, then its options."""
    lines = []
    for name, (model, _, summary) in _SCENARIOS.items():
        lines.append(f"sim:{name}: {summary}")
        lines += [f"    {line}" for line in describe_model(model)]
    return lines
