"""``--set`` spelt the same in every command: ``ESTIMATOR.key=value`` names the estimator an
option is for; a bare ``key=value`` is accepted where one estimator runs (``workbench run``,
or a bag or a suite restricted to one estimator)."""

from __future__ import annotations

from datasets.errors import InputError
from datasets.options import parse_assignments


def settings_by_estimator(
    assignments: list[str] | tuple[str, ...], estimators: list[str]
) -> dict[str, dict[str, str]]:
    """``["ekf-slam.velocity_walk_m_s_sqrt_s=0.1"]`` -> ``{"ekf-slam":
    {"velocity_walk_m_s_sqrt_s": "0.1"}, ...}`` with an entry (possibly empty) for each of ``estimators``, the names the
    command runs. ``InputError`` for an estimator the command does not run, and for a bare
    key when it runs several."""
    from workbench.registry import ESTIMATORS

    registered = {entry.name for entry in ESTIMATORS}
    settings: dict[str, dict[str, str]] = {name: {} for name in estimators}
    for key, value in parse_assignments(list(assignments), "--set").items():
        name, dot, option = key.partition(".")
        if dot and name in registered:
            if name not in settings:
                raise InputError(
                    f"--set {key}: '{name}' is not among the estimators this command runs "
                    f"({', '.join(estimators)})"
                )
            if not option:
                raise InputError(f"--set expects ESTIMATOR.key=value, got '{key}={value}'")
            settings[name][option] = value
        elif len(estimators) == 1:
            settings[estimators[0]][key] = value
        else:
            raise InputError(
                f"--set {key}={value}: name the estimator, ESTIMATOR.key=value "
                f"(this command runs {', '.join(estimators)})"
            )
    return settings
