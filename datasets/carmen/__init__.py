"""CARMEN laser logs: ``carmen:FILE.clf[.bz2]`` (the Intel, Freiburg 079 and MIT CSAIL logs of
the Radish "SLAM evaluation" collection; Kümmerle et al., Autonomous Robots 27(4), 2009).

What the stream contains (planar, time-ordered; one frame per laser scan):
- at every scan after the first, ``Odometry(t, relative_pose=(dx, dy, dtheta), dt,
  frame=True)``: the odometry increment since the previous scan, in its body frame, with
  the covariance of the odometry noise model (``datasets.carmen.noise``); ``frame=True``
  makes every scan a frame, so every estimator reports a pose at every scan's stamp
  (``Estimate.frame_times``, the runs' ``frames_without_pose``);
- then the scan's corners as a ``LandmarkScan`` without ids (``datasets.laser2d``: split-and-
  merge lines, total-least-squares fits, corners with first-order covariances, emitted once
  the previous scan confirms them).
Times are the lines' ``ipc_timestamp`` [s]. The start (``initial_state``) is the first scan's
pose, at the origin. No ground truth ships with the logs (``ground_truth`` is None; relations
come with ``--data relations=FILE``, for every dataset). The logged laser poses ``x y theta``
(corrected by the logging software of the day) are never used.

Decided at load, counted in ``Sequence.counts`` and printed as one line each
(``Sequence.warnings``, with the evidence):
- *stamps*: duplicated lines dropped; lines out of time order repaired where their stamp
  reads as unpadded microseconds, else dropped (``datasets.carmen.stamps``; the Intel log
  has about a thousand);
- *odometry*: the scans' own odometry fields by default, and how far the ``ODOM`` lines
  are from them; stale odometry spread (``datasets.carmen.odometry``);
- *laser offset*: from the ``PARAM`` lines, a ``ROBOTLASER1`` line, or 0 (printed);
- *skipped* message types and the other laser's lines.

Modules: ``messages`` (the message types), ``log_parsing`` (lines to messages), ``stamps``
(time order), ``odometry`` (odometry at the scans), ``noise`` (the odometry noise model),
``options``, ``assembly`` (the ``Sequence``).
"""

from __future__ import annotations

from pathlib import Path

from datasets.carmen.assembly import carmen_sequence
from datasets.carmen.log_parsing import parse_log
from datasets.carmen.options import CarmenOptions
from datasets.errors import InputError
from datasets.sequence import Sequence


def load(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """Load ``carmen:FILE`` (``seed`` is unused: real data)."""
    from datasets.options import build_model, nest_dotted

    if not argument:
        raise InputError(
            "dataset carmen needs a log file: carmen:FILE.clf or carmen:FILE.clf.bz2 "
            "(e.g. carmen:../shared/data/carmen-logs/intel.clf.bz2)"
        )
    settings = build_model(CarmenOptions, nest_dotted(options), f"carmen:{argument} --data")
    return carmen_sequence(parse_log(Path(argument).expanduser()), settings, f"carmen:{argument}")


def describe() -> list[str]:
    """Lines for ``workbench list --verbose``."""
    from datasets.laser2d.corners import Laser2dCornerSettings
    from datasets.options import describe_model

    own = [line for line in describe_model(CarmenOptions) if not line.startswith("corner ")]
    return ["carmen:FILE.clf[.bz2]  --data options:"] + [
        "  " + line
        for line in own + [f"corner.{line}" for line in describe_model(Laser2dCornerSettings)]
    ]


__all__ = ["CarmenOptions", "carmen_sequence", "describe", "load", "parse_log"]
