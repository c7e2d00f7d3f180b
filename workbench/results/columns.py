"""The columns a paper table can show, and the presets that pick them (``workbench report
--table accuracy|consistency|cost|all|COL,...``, a suite's ``table:`` key).

A column is named as in ``table.csv``: a metrics.json key (``ate_rmse_m``: the mean and std
over runs), ``ate_over_reference`` (a suite's reference ratio), ``anees_B_per_dof`` (the
consistency cell of block B, with its verdict) or ``nis_per_dof`` (every update of every run
pooled). Each carries its header, unit, what it means (for the caption) and its direction:
which value is best (lower, higher, or closest to 1), or none.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from datasets.errors import InputError
from workbench.results.consistency import TABLE_BLOCKS
from workbench.results.summary import REFERENCE_KEY, STAT_KEYS

LOWER = "lower"
HIGHER = "higher"
ONE = "one"
"""Directions: the best value is the lowest, the highest, or the closest to 1 (smallest
``|ln x|``: 0.5 and 2 are equally far)."""

STAT = "stat"
RATIO = "ratio"
CELL = "cell"
POOLED = "pooled"
"""Kinds: a ``Stat`` (mean, std over runs), a ratio of means (no std), a consistency cell
(value per dof and verdict), the pooled NIS per dof (one number)."""


@dataclass(frozen=True)
class Column:
    """One column of a paper table.

    Attributes:
        key: its ``table.csv`` name (module docstring).
        header: the header's lines (the last one the unit, "" when it has none).
        kind: ``stat``, ``ratio``, ``cell`` or ``pooled``.
        direction: ``lower``, ``higher``, ``one`` or None (no best value).
        meaning: what a cell is, a phrase for the caption ("" to say nothing).
        group: a heading shared by adjacent columns ("" for none).
    """

    key: str
    header: tuple[str, ...]
    kind: str
    direction: str | None
    meaning: str = ""
    group: str = ""

    @property
    def block(self) -> str:
        """The consistency block of a ``cell`` column (``anees_pose_per_dof`` -> ``pose``)."""
        return self.key.removeprefix("anees_").removesuffix("_per_dof")


_BLOCK_NAMES = {
    "pose": "pose",
    "velocity": "velocity",
    "gyro_bias": "gyro bias",
    "accel_bias": "accel bias",
    "map": "map",
    "nis": "NIS",
}

_NAMED = (
    Column(
        "ate_rmse_m",
        ("ATE", "[m]"),
        STAT,
        LOWER,
        "ATE: RMSE of the position error after aligning the estimate to the reference "
        "(SE(3) in 3-D, SE(2) in the plane)",
    ),
    Column(
        REFERENCE_KEY,
        ("ATE÷ref", ""),
        RATIO,
        LOWER,
        "ATE÷ref: the row's mean ATE over the reference estimator's on the same dataset",
    ),
    Column(
        "ate_rmse_smoothed_m",
        ("ATE sm.", "[m]"),
        STAT,
        LOWER,
        "ATE sm.: the ATE of the smoothed trajectory",
    ),
    Column(
        "rpe_trans_rmse_m",
        ("RPE tr.", "[m]"),
        STAT,
        LOWER,
        "RPE: RMSE of the relative pose error between consecutive poses (1 frame), "
        "translation (tr.) and rotation (rot.)",
    ),
    Column("rpe_rot_rmse_deg", ("RPE rot.", "[deg]"), STAT, LOWER),
    Column(
        "final_orientation_error_deg",
        ("final or.", "[deg]"),
        STAT,
        LOWER,
        "final or.: the orientation error at the last pose the reference covers",
    ),
    Column(
        "gps_holdout_rmse_m",
        ("GPS h.o.", "[m]"),
        STAT,
        LOWER,
        "GPS h.o.: RMSE of the estimated positions at GPS fixes held out of the estimation, "
        "without alignment",
    ),
    Column(
        "gps_holdout_rmse_smoothed_m",
        ("GPS h.o. sm.", "[m]"),
        STAT,
        LOWER,
        "GPS h.o. sm.: the same for the smoothed trajectory",
    ),
    Column(
        "landmark_rmse_m",
        ("map RMSE", "[m]"),
        STAT,
        LOWER,
        "map RMSE: RMSE of the final map's landmarks matched to true ones",
    ),
    Column("landmarks_in_map", ("landmarks", ""), STAT, None, "landmarks: in the final map"),
    Column("association_precision", ("assoc.", "precision"), STAT, HIGHER),
    Column("association_recall", ("assoc.", "recall"), STAT, HIGHER),
    Column(
        "frontend_max_deviation_m",
        ("max dev.", "[m]"),
        STAT,
        LOWER,
        "vs front end: each estimate against its lidar front end's own trajectory, both from "
        "the same start: largest position deviation, as a share of the front end's path, and "
        "the yaw difference at the last frame (estimate minus front end)",
        group="vs front end",
    ),
    Column(
        "frontend_max_deviation_percent_path",
        ("max dev.", "[% path]"),
        STAT,
        LOWER,
        group="vs front end",
    ),
    Column(
        "frontend_final_yaw_diff_deg",
        ("final yaw", "[deg]"),
        STAT,
        None,
        group="vs front end",
    ),
    Column(
        "frames",
        ("frames", ""),
        STAT,
        None,
        "frames: where the data expect a pose (landmark scans, lidar frames)",
    ),
    Column(
        "frames_without_pose",
        ("frames", "no pose"),
        STAT,
        LOWER,
        "no pose: frames the estimate has no pose at",
    ),
    Column(
        "time_per_frame_ms",
        ("time/frame", "[ms]"),
        STAT,
        LOWER,
        "time/frame: a run's wall-clock time over its frames",
    ),
    Column(
        "time_total_s",
        ("time/run", "[s]"),
        STAT,
        LOWER,
        "time/run: wall-clock time of a whole run, final optimisation included",
    ),
    Column(
        "time_per_step_ms_median",
        ("step med.", "[ms]"),
        STAT,
        LOWER,
        "step med., step p99: median and 99th percentile of the time per processed measurement",
    ),
    Column("time_per_step_ms_p99", ("step p99", "[ms]"), STAT, LOWER),
    Column(
        "nis_per_dof",
        ("NIS pooled", "per dof"),
        POOLED,
        ONE,
        "NIS pooled: every update of every run summed over their summed dof",
    ),
)

_UNITS = {"_m": "[m]", "_deg": "[deg]", "_ms": "[ms]", "_s": "[s]"}


def _derived(key: str) -> Column:
    """A column for a metrics.json key without a hand-written header: the key's words and
    its unit suffix; best lower for errors and times, higher for precision and recall."""
    name, unit = key, ""
    for suffix, text in _UNITS.items():
        if key.endswith(suffix):
            name, unit = key[: -len(suffix)], text
            break
    if "rmse" in key or "error" in key or key.startswith("time_"):
        direction: str | None = LOWER
    elif key.endswith(("precision", "recall")):
        direction = HIGHER
    else:
        direction = None
    return Column(key, (name.replace("_", " "), unit), STAT, direction)


def _cell(block: str) -> Column:
    group = "NIS" if block == "nis" else "NEES per dof"
    name = "per dof" if block == "nis" else _BLOCK_NAMES[block]
    return Column(f"anees_{block}_per_dof", (name, ""), CELL, ONE, group=group)


def _catalogue() -> dict[str, Column]:
    named = {column.key: column for column in _NAMED}
    found = {key: named.get(key) or _derived(key) for key in STAT_KEYS}
    found[REFERENCE_KEY] = named[REFERENCE_KEY]
    found.update({f"anees_{block}_per_dof": _cell(block) for block in TABLE_BLOCKS})
    found["nis_per_dof"] = named["nis_per_dof"]
    return found


COLUMNS: dict[str, Column] = _catalogue()
"""Every column a table can show, by its ``table.csv`` name."""

PRESETS: dict[str, tuple[str, ...]] = {
    "accuracy": (
        "ate_rmse_m",
        REFERENCE_KEY,
        "ate_rmse_smoothed_m",
        "rpe_trans_rmse_m",
        "rpe_rot_rmse_deg",
        "final_orientation_error_deg",
        "gps_holdout_rmse_m",
        "gps_holdout_rmse_smoothed_m",
    ),
    "consistency": tuple(f"anees_{block}_per_dof" for block in TABLE_BLOCKS),
    "cost": ("time_total_s", "time_per_step_ms_median", "time_per_step_ms_p99"),
}
ALL = "all"
CUSTOM = "custom"
"""The name of the table a column list makes (``table_custom.tex``)."""
DEFAULT_TABLE = ALL


def parse_table_choice(text: str, option: str = "--table") -> list[tuple[str, tuple[Column, ...]]]:
    """``accuracy`` / ``consistency`` / ``cost`` -> that preset; ``all`` -> the three;
    ``COL,COL,...`` (``table.csv`` names) -> one ``custom`` table of those columns.
    Returns ``[(name, columns), ...]``; ``InputError`` naming an unknown name."""
    choice = text.strip()
    if choice == ALL:
        return [(name, tuple(COLUMNS[key] for key in keys)) for name, keys in PRESETS.items()]
    if choice in PRESETS:
        return [(choice, tuple(COLUMNS[key] for key in PRESETS[choice]))]
    keys = list(dict.fromkeys(part.strip() for part in choice.split(",") if part.strip()))
    unknown = [key for key in keys if key not in COLUMNS]
    if not keys or unknown:
        name = unknown[0] if unknown else text
        close = difflib.get_close_matches(name, [*PRESETS, ALL, *COLUMNS], n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise InputError(
            f"{option} {text!r}: '{name}' is neither a preset ({', '.join([*PRESETS, ALL])}) "
            f"nor a table.csv column{hint} (columns: {', '.join(COLUMNS)})"
        )
    return [(CUSTOM, tuple(COLUMNS[key] for key in keys))]


TABLE_HELP = (
    f"LaTeX tables: {', '.join(PRESETS)} or {ALL} (one file each), or table.csv columns "
    "COL,COL,... (table_custom.tex)"
)
"""The ``--table`` option's help."""
