"""Has a fixed-lag window stopped fitting its own new factors? ``WindowHealth``.

A fixed-lag smoother holds the states that left its window only as linear marginal factors,
fixed at the estimate of the moment they left. A loop that closes with a large correction
through them can make the window's Gauss-Newton steps swing instead of settle: on the Intel
laser log the first loop closure turns the heading by 23.9 deg in one step, and the fixed-lag
window then swings by 6, 18 and 66 deg in its next updates, a landmark runs off to 1374 m,
and GTSAM finds the system indeterminate 826 s later (``docs/laser2d.md``). Nothing in the
association sees it: the window's predictions and their covariances are equally wrong, so
the sightings stay inside their gates.

What does see it: after every update, the chi-square per degree of freedom of *that update's
new factors* at the updated estimate (``2 E / dof``, with ``E`` GTSAM's factor error, the
half squared whitened residual). A window that took its new measurements has it near the
noise level; one that could not has it orders of magnitude above. Measured with the default
options (diagnostic outside the repo): UTIAS robots 1 and 5, 6719 and 8888 updates, at most
2.8 and 3.6 (robot 5's 40 deg correction included); the Intel log's first 1300 scans: 1774 at
the loop closure, then 90, 14447, 2212 and 33 updates above 20 within 16 s; iSAM2 on the same
scans: 1774 at the loop closure once, then never above 2 (it relinearises and settles).

One update above ``UNSETTLED_CHI2_PER_DOF`` is a large correction, not yet a failure, and a
few in a row are a run of them: iSAM2 on the MIT CSAIL laser log has 12 such updates, at most
4 within 30 s, and agrees with the batch smoother to 0.0125 m. The window has diverged when
``UNSETTLED_UPDATES`` of them fall within ``UNSETTLED_WINDOW_S``, from the first of them:
the fixed-lag smoother on the Intel log's first 1300 scans has 30 within 30 s from its loop
closure (228 s in), on MIT CSAIL 104 over the run, 66 within 30 s at most, the first ten
within 30 s from 349 s in, and on Freiburg 079 54, 19 within 30 s at most, from 737 s in
(iSAM2 there: 11, never two within 30 s). UTIAS robots 1-5, Victoria Park, the KITTI clips
and the simulated loop, rover and laser building hold (largest 14.5, sim:laser2d, once).
"""

from __future__ import annotations

import gtsam

UNSETTLED_CHI2_PER_DOF = 25.0
"""Chi-square per dof of an update's new factors above which the update did not settle:
for 2 dof the chance of more under a consistent model is e^-25 (1e-11); the fixed-lag
smoother reads at most 3.6 on UTIAS and 9.0 on Victoria Park (module docstring)."""

UNSETTLED_UPDATES = 10
"""Unsettled updates within ``UNSETTLED_WINDOW_S`` that make a divergence: 2.5x the most
iSAM2 has on any shared recording (4, MIT CSAIL), half or less of what a diverged window
shows (19 to 66; module docstring)."""

UNSETTLED_WINDOW_S = 30.0
"""The span [s] within which ``UNSETTLED_UPDATES`` unsettled updates count as divergence."""


def new_factor_chi2_per_dof(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values
) -> float | None:
    """``2 E / dof`` of the factors of ``graph`` whose variables ``values`` holds (None when
    none: an update of priors on variables already gone)."""
    error, dof = 0.0, 0
    for index in range(graph.size()):
        factor = graph.at(index)
        if factor is None or not all(values.exists(key) for key in factor.keys()):
            continue
        error += factor.error(values)
        dof += factor.dim()
    return 2.0 * error / dof if dof else None


class WindowHealth:
    """The unsettled updates of a run and, once established, when it diverged.

    Attributes:
        unsettled: (time [s], chi-square per dof) of every unsettled update.
        diverged_at: the time [s] of the first of ``UNSETTLED_UPDATES`` unsettled updates
            within ``UNSETTLED_WINDOW_S``, None while the window holds.
    """

    def __init__(self) -> None:
        self.unsettled: list[tuple[float, float]] = []
        self.diverged_at: float | None = None

    def check(self, t: float, chi2_per_dof: float | None) -> bool:
        """Record the update at ``t`` [s]; True when this update establishes the divergence."""
        if chi2_per_dof is None or chi2_per_dof <= UNSETTLED_CHI2_PER_DOF:
            return False
        self.unsettled.append((float(t), float(chi2_per_dof)))
        if self.diverged_at is not None:
            return False
        recent = [u for u, _ in self.unsettled if u >= t - UNSETTLED_WINDOW_S]
        if len(recent) < UNSETTLED_UPDATES:
            return False
        self.diverged_at = recent[0]
        return True
