"""The option vocabulary every estimator shares: the same name means the same thing in
every filter and smoother (``--set gate_probability=0.99`` gates the same way everywhere).

Estimator configs inherit these pydantic models, so the keys stay flat on the command line
and ``workbench list --verbose`` shows them with one description. The algorithms behind
the association options live in ``filters.association``; the options of an estimator's
model (motion noise, priors, gaps, landmark noise) in ``datasets.model_options``.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from pydantic.fields import FieldInfo

from datasets.errors import InputError

DEFAULT_GATE_PROBABILITY = 0.99
DEFAULT_NEW_LANDMARK_PROBABILITY = 0.9999
DEFAULT_ID_GATE_PROBABILITY = 0.9999
DEFAULT_MAX_JCBB_NODES = 2000
"""Measured on sim:guerreiro-loop (ids withheld, seed 0): at 20,000 nodes the revisit scans
hit the cap and ekf-slam took ~25 min; at 2,000 ~1.5 min with the same association
precision (0.859 vs 0.858)."""


class AssociationOptions(BaseModel):
    """How landmark sightings are associated (``filters.association.AssociationPolicy``)."""

    model_config = ConfigDict(extra="forbid")
    association: Literal["auto", "ids", "jcbb", "nearest"] = Field(
        "auto",
        description="auto: the scan's ids when it has them, else JCBB; ids: require ids; "
        "jcbb / nearest: ignore ids (joint compatibility, or gated nearest neighbour)",
    )
    gate_probability: float = Field(
        DEFAULT_GATE_PROBABILITY,
        gt=0,
        lt=1,
        description="chi-square gate probability of geometric association (individual and joint)",
    )
    new_landmark_probability: float = Field(
        DEFAULT_NEW_LANDMARK_PROBABILITY,
        gt=0,
        lt=1,
        description="an unassociated sighting starts a landmark only when outside this chi-square "
        "gate of every landmark (between the gates it is ambiguous: neither used nor mapped)",
    )
    id_gate_probability: float | None = Field(
        DEFAULT_ID_GATE_PROBABILITY,
        gt=0,
        lt=1,
        description="with ids: a sighting whose NIS exceeds this chi-square quantile is used with "
        "its noise inflated so that its NIS equals the gate, and counted (never rejected: that "
        "can leave a filter blind); None: no gate",
    )
    max_jcbb_nodes: int = Field(
        DEFAULT_MAX_JCBB_NODES,
        ge=1,
        description="cap on JCBB interpretation-tree nodes per scan (bounded run time; a "
        "truncated search is recorded as an event)",
    )


class RecordingOptions(BaseModel):
    """What an estimator records besides its per-step state."""

    model_config = ConfigDict(extra="forbid")
    snapshot_interval_s: float = Field(
        5.0,
        ge=0,
        description="landmark map snapshots (with their joint covariance, for the map NEES) in "
        "the history at most this often [s] (0: every scan); the final map is always recorded",
    )


class MeasurementNoiseOptions(BaseModel):
    """Scales on the noise the data states (a tuning knob, recorded in the run's config)."""

    model_config = ConfigDict(extra="forbid")
    measurement_noise_scale: float = Field(
        1.0, gt=0, description="multiplies the landmark covariances the scans carry"
    )


ESTIMATOR_NOTE = " [here: "
"""Opens the part of a shared field's description that one estimator adds (``for_estimator``)."""


def for_estimator(model: type[BaseModel], name: str, note: str, **changes: Any) -> Any:
    """The shared field ``name`` of ``model`` as one estimator declares it: the same
    description with ``note`` appended (its own default and why: the paper's value, say),
    and ``changes`` (``default=...``) applied. Redeclare it with the same annotation::

        velocity_walk_m_s_sqrt_s: float | list[float] = for_estimator(
            VelocityWalkOptions, "velocity_walk_m_s_sqrt_s", "0.3: ...", default=0.3
        )

    ``tests/test_option_vocabulary.py`` accepts a name with two defaults only so."""
    shared = model.model_fields[name]
    return FieldInfo.merge_field_infos(
        shared, Field(**changes), description=f"{shared.description}{ESTIMATOR_NOTE}{note}]"
    )


def per_body_axis(value: float | list[float], dimension: int, name: str) -> np.ndarray:
    """An option given for every axis (one number) or per body axis ([forward, lateral(,
    vertical)]) as a (dimension,) array; ``InputError`` naming the option when a value is
    negative or the list has the wrong length."""
    values = np.asarray(value, dtype=float).ravel()
    if values.size == 1:
        values = np.full(dimension, float(values[0]))
    if values.size != dimension or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise InputError(
            f"option {name}: expected one value >= 0 or {dimension} (one per body axis), got {value}"
        )
    return values
