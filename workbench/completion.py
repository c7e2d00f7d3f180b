"""Shell completion of names (``workbench --install-completion`` sets the shell up): the
registered estimators, the dataset names and prefixes, the built-in suites. Cheap: the
registry's table only, nothing imported."""

from __future__ import annotations


def estimator_names(incomplete: str) -> list[str]:
    from workbench.registry import ESTIMATORS

    return [entry.name for entry in ESTIMATORS if entry.name.startswith(incomplete)]


def dataset_names(incomplete: str) -> list[str]:
    """Full names where the registry knows them (the simulator's scenarios, the gtsam
    wheel's data) and ``PREFIX:`` for families that take a path."""
    from workbench.registry import DATASETS

    names: list[str] = []
    for entry in DATASETS:
        if entry.argument in (None, "SCENARIO"):
            names += list(entry.examples) or [entry.prefix]
        else:
            names.append(f"{entry.prefix}:")
    return [name for name in dict.fromkeys(names) if name.startswith(incomplete)]


def suite_names(incomplete: str) -> list[str]:
    from workbench.suite_files import builtin_suites

    return [name for name in builtin_suites() if name.startswith(incomplete)]
