"""Metrics: pure functions from trajectories, estimates and ground truth to numbers (no I/O).

Modules, one idea each:
    ``timestamps``        evo's nearest-stamp pairing; truth at given times (interpolated)
    ``alignment``         Umeyama SE(3) / Sim(3) / SE(2) alignment
    ``ate``               absolute trajectory error (``ate_report`` = ``evo_ape``)
    ``rpe``               relative pose error by frames or metres (``rpe_report`` =
                          ``evo_rpe``) and the KITTI segment metric
    ``orientation``       Aghili eq. (43) orientation error
    ``consistency``       NEES, NIS, averaged NEES with chi-square bounds, pose errors
    ``state_errors``      errors of an estimate's blocks against the truth; NEES series
    ``data_association``  association precision/recall and loop-closure precision
    ``summary``           ``compute_metrics``: the flat ``metrics.json`` dictionary
"""

from workbench.metrics.ate import ate_report
from workbench.metrics.consistency import AveragedNees, averaged_nees, chi2_interval, nees
from workbench.metrics.rpe import kitti_segment_errors, rpe_report
from workbench.metrics.state_errors import NeesSeries, nees_series
from workbench.metrics.summary import compute_metrics

__all__ = [
    "AveragedNees",
    "NeesSeries",
    "ate_report",
    "averaged_nees",
    "chi2_interval",
    "compute_metrics",
    "kitti_segment_errors",
    "nees",
    "nees_series",
    "rpe_report",
]
