"""Data association shared by every filter and smoother: individual compatibility gating,
JCBB (Neira and Tardos 2001), gated nearest neighbour, association by ids, and the policy
that turns them into one typed decision per sighting.

It speaks only in *predicted measurements*: each caller supplies

- ``measured`` ``z_j`` (k, d) with covariance ``R`` (per measurement blocks (k, d, d), or the
  full (k*d, k*d) matrix),
- ``predicted`` ``h_i`` (m, d), the map landmarks as the sensor would see them, with the
  *joint* covariance ``H P H^T`` of all predictions (m*d, m*d): the off-diagonal blocks are
  what makes the joint compatibility test differ from the individual one,
- optionally the cross covariance ``cov(z, h)`` (k*d, m*d), zero for an ordinary scan
  (independent sensor noise); loop closing, where both sides are state landmarks, needs it.

Imports numpy, scipy and ``datasets`` only: nothing else from ``filters`` (the smoothers
import it without loading any filter).

Modules: ``compatibility`` (the chi-square gate of one pair), ``jcbb`` (the joint search
and the nearest-neighbour baseline), ``policy`` (``AssociationPolicy``, ``ScanAssociation``), ``hypotheses`` (the k most
likely joint interpretations of a scan, for multi-hypothesis estimators).
"""

from filters.association.compatibility import chi2_gate, individual_compatibility
from filters.association.jcbb import (
    AssociationResult,
    associate_jcbb,
    associate_nearest_neighbour,
)
from filters.association.policy import (
    AssociationPolicy,
    Decision,
    Predictor,
    Reason,
    ScanAssociation,
)

__all__ = [
    "AssociationPolicy",
    "AssociationResult",
    "Decision",
    "Predictor",
    "Reason",
    "ScanAssociation",
    "associate_jcbb",
    "associate_nearest_neighbour",
    "chi2_gate",
    "individual_compatibility",
]
