"""Which pose topic of a bag is wheel odometry: decided from the messages, printed with the
evidence, overridable.

A bag's ``nav_msgs/Odometry`` topics are of several kinds that look alike by type: wheel
odometry (``/odom``, ``/wheel/odometry``: frame ``odom``, child ``base_link``, smooth), an
estimator's output (robot_localization's ``/odometry/filtered``, a SLAM system's), a GPS
converted to a pose (``/odometry/gps``), or a simulator's ground truth (``/ground_truth``,
frame ``world``, zero covariance). Only the first is a motion input; none is truth unless
named (``ground_truth_topic``).

Evidence read per candidate (``inspect_pose_topic``, from its first ``EVIDENCE_MESSAGES``
messages): message type, frame id and child frame id, rate, whether the pose and twist
covariances are zero, placeholders or meaningful, whether the pose jumps (a step longer than
``JUMP_MIN_M`` and ``JUMP_FACTOR`` times the median step: an estimate corrected by absolute
measurements), whether the pose moves at all while the twist does, and what the topic's name
says. A candidate is ruled out by a global frame id (``GLOBAL_FRAMES``: a localisation, GPS
or truth frame), by jumps, by a name that says it is an estimator's output or an absolute
source (``NOT_WHEEL_WORDS``), or by a pose that never moves and a twist that is zero (no
motion information). Among the rest the best score wins (frame ``odom``, a child frame,
a wheel-like name, a twist); a tie is an ``InputError`` naming the candidates and the
option. Only ``nav_msgs/Odometry`` topics are candidates; a ``PoseStamped`` or
``PoseWithCovarianceStamped`` topic is differenced as odometry only when named
(``odometry_topic``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages
from datasets.bags.message_types import ODOMETRY, POSE_TYPES
from datasets.bags.read_report import ReadReport
from datasets.bags.wheel_odometry import (
    PoseSample,
    WheelNoise,
    meaningful_axes,
    noise_policy,
    pose_sample,
)
from datasets.errors import InputError, did_you_mean

EVIDENCE_MESSAGES = 200
"""Messages read per pose topic to decide its role (4 s of a 50 Hz odometry)."""
JUMP_MIN_M = 0.25
"""A step shorter than this [m] is never a jump."""
JUMP_FACTOR = 8.0
"""A step this many times the topic's median step (and longer than ``JUMP_MIN_M``) is a
jump: wheel odometry integrates, it does not leap."""
GLOBAL_FRAMES = ("map", "world", "earth", "utm", "enu", "ned", "gps", "local_origin")
"""Frame ids of a global frame (REP-105 ``map`` and ``earth``, simulators' ``world``): a pose
there is localisation, GPS or truth, not wheel odometry (REP-105: odometry is in ``odom``)."""
NOT_WHEEL_WORDS = (
    "filtered",
    "ekf",
    "ukf",
    "fused",
    "fusion",
    "estimate",
    "estimated",
    "localization",
    "localisation",
    "gps",
    "gnss",
    "navsat",
    "truth",
    "ground",
    "groundtruth",
    "gt",
    "vicon",
    "mocap",
    "optitrack",
    "slam",
    "lio",
    "vio",
    "vins",
    "icp",
    "lidar",
    "laser",
    "visual",
    "camera",
)
"""Words of a topic name that say it is an estimator's output or an absolute source."""
WHEEL_WORDS = ("wheel", "wheels", "encoder", "encoders", "odom")


@dataclass(frozen=True)
class PoseTopicEvidence:
    """What the first messages of a pose topic show (module docstring)."""

    topic: str
    msgtype: str
    messages: int
    rate_hz: float | None
    frame_id: str
    child_frame_id: str
    pose_covariance: str  # "zero", "placeholders", "meaningful", "none"
    twist_covariance: str
    twist_moves: bool
    pose_moves: bool
    largest_step_m: float
    median_step_m: float
    jumps: int
    first: PoseSample | None
    message_interval_s: float

    def words(self) -> set[str]:
        return topic_words(self.topic)

    def global_frame(self) -> bool:
        frame = self.frame_id.lower().lstrip("/")
        return frame in GLOBAL_FRAMES or frame.endswith(("/map", "_map"))

    def ruled_out(self) -> str | None:
        """Why it is not wheel odometry, or None."""
        if self.messages < 2:
            return f"{self.messages} message(s)"
        if self.global_frame():
            return f"global frame '{self.frame_id}'"
        said = not_wheel_words(self.topic)
        if said:
            return f"its name says an estimator's output or an absolute source ({', '.join(said)})"
        if self.jumps:
            return (
                f"it jumps ({self.jumps} step(s) up to {self.largest_step_m:.3g} m against a "
                f"median {self.median_step_m:.3g} m: corrected by absolute measurements)"
            )
        if not self.pose_moves and not self.twist_moves:
            return "neither its pose nor its twist moves"
        return None

    def score(self) -> int:
        return (
            int("odom" in self.frame_id.lower())
            + int(bool(self.child_frame_id))
            + int(bool(self.words() & set(WHEEL_WORDS)))
            + int(self.twist_moves)
        )

    def text(self) -> str:
        """The evidence as a phrase."""
        rate = f"{self.rate_hz:.3g} Hz" if self.rate_hz else "rate unknown"
        frames = f"frame '{self.frame_id}'" + (
            f" -> '{self.child_frame_id}'" if self.child_frame_id else ""
        )
        motion = (
            f"steps up to {self.largest_step_m:.3g} m (median {self.median_step_m:.3g} m)"
            if self.pose_moves
            else "pose still"
        )
        twist = (
            ""
            if self.msgtype != ODOMETRY
            else f", twist {'moving' if self.twist_moves else 'zero'} with "
            f"{self.twist_covariance} covariance"
        )
        return (
            f"{self.msgtype.replace('/msg/', '/')}, {frames}, {rate}, {self.messages} "
            f"messages read, pose covariance {self.pose_covariance}{twist}, {motion}"
        )


def topic_words(topic: str) -> set[str]:
    """The words of a topic name (split at ``/ _ - .``), lower case."""
    return {word for word in re.split(r"[/_\-.]+", topic.lower()) if word}


def not_wheel_words(topic: str) -> list[str]:
    """The words of a topic's name that rule it out as wheel odometry (``NOT_WHEEL_WORDS``),
    sorted; empty when its name allows it."""
    return sorted(topic_words(topic) & set(NOT_WHEEL_WORDS))


def _covariance_kind(covariance: np.ndarray | None) -> str:
    if covariance is None:
        return "none"
    diagonal = np.diag(np.asarray(covariance, dtype=float).reshape(6, 6))
    if not np.any(diagonal):
        return "zero"
    if meaningful_axes(covariance).any():
        return "meaningful"
    return "placeholders"


def inspect_pose_topic(reader, path: Path, topic: str, msgtype: str) -> PoseTopicEvidence:
    """The evidence of ``topic`` from its first ``EVIDENCE_MESSAGES`` messages."""
    samples: list[PoseSample] = []
    pose_covariance = None
    frame_id, child = "", ""
    for _, _, stamp, message in iter_messages(reader, path, [topic], report=ReadReport()):
        sample = pose_sample(message, msgtype, stamp)
        if not (np.all(np.isfinite(sample.position)) and np.all(np.isfinite(sample.quaternion))):
            continue
        if not samples:
            frame_id = str(message.header.frame_id)
            child = str(getattr(message, "child_frame_id", "") or "")
            covariance = getattr(message.pose, "covariance", None)
            pose_covariance = None if covariance is None else np.asarray(covariance, float)
        if samples and stamp <= samples[-1].t:
            continue
        samples.append(sample)
        if len(samples) >= EVIDENCE_MESSAGES:
            break
    times = np.array([s.t for s in samples])
    positions = np.array([s.position for s in samples]).reshape(-1, 3)
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    median = float(np.median(steps)) if steps.size else 0.0
    jumps = int(np.count_nonzero((steps > JUMP_MIN_M) & (steps > JUMP_FACTOR * median)))
    intervals = np.diff(times)
    interval = float(np.median(intervals)) if intervals.size else 0.0
    twists = [
        np.linalg.norm(s.linear) + np.linalg.norm(s.angular)
        for s in samples
        if s.linear is not None
    ]
    first = samples[0] if samples else None
    return PoseTopicEvidence(
        topic=topic,
        msgtype=msgtype,
        messages=len(samples),
        rate_hz=1.0 / interval if interval > 0 else None,
        frame_id=frame_id,
        child_frame_id=child,
        pose_covariance=_covariance_kind(pose_covariance),
        twist_covariance=_covariance_kind(first.twist_covariance if first else None),
        twist_moves=bool(twists) and float(np.max(twists)) > 1e-9,
        pose_moves=bool(steps.size) and float(np.max(steps)) > 1e-9,
        largest_step_m=float(np.max(steps)) if steps.size else 0.0,
        median_step_m=median,
        jumps=jumps,
        first=first,
        message_interval_s=interval,
    )


@dataclass(frozen=True)
class OdometryRole:
    """The decision: the odometry topic (None: none), its evidence, and the line to print."""

    topic: str | None
    evidence: PoseTopicEvidence | None
    text: str
    from_twist: bool = False

    def noise(self, choice: str) -> tuple[WheelNoise, str]:
        """The chosen topic's noise model for ``--data odometry_noise=choice`` and the line of
        evidence for it (``wheel_odometry.noise_policy``, read from the topic's first message)."""
        if self.topic is None or self.evidence is None:
            raise ValueError("no odometry topic was chosen")
        return noise_policy(
            choice, self.evidence.first, self.evidence.message_interval_s, self.topic
        )


def choose_odometry(
    reader,
    path: Path,
    types: dict[str, str],
    named: str | None,
    truth: str | None,
) -> OdometryRole:
    """The wheel-odometry topic of a bag (module docstring). ``named``: the
    ``odometry_topic`` option (checked: it must exist, carry a pose and not be the truth
    topic)."""
    if named:
        if named not in types:
            listed = ", ".join(t for t, m in sorted(types.items()) if m in POSE_TYPES) or "none"
            raise InputError(
                f"{path}: no topic '{named}' (odometry_topic){did_you_mean(named, list(types))}; "
                f"pose topics: {listed}"
            )
        if types[named] not in POSE_TYPES:
            raise InputError(
                f"{path}: topic '{named}' is {types[named]}, not {' or '.join(POSE_TYPES)} "
                "(odometry_topic)"
            )
        if named == truth:
            raise InputError(
                f"{path}: {named} is named both as the odometry input (odometry_topic) and as "
                "the ground truth (ground_truth_topic): an input scored against itself"
            )
        evidence = inspect_pose_topic(reader, path, named, types[named])
        if evidence.messages < 2:
            raise InputError(
                f"{path}: odometry_topic {named} has {evidence.messages} usable pose(s)"
            )
        doubt = evidence.ruled_out()
        from_twist = _from_twist(evidence)
        return OdometryRole(
            named,
            evidence,
            f"odometry: {named} as named (odometry_topic): {evidence.text()}"
            + (f"; by the evidence it would not be taken ({doubt})" if doubt else "")
            + _increments_text(from_twist),
            from_twist,
        )
    found = [
        inspect_pose_topic(reader, path, topic, msgtype)
        for topic, msgtype in sorted(types.items())
        if msgtype == ODOMETRY and topic != truth
    ]
    if not found:
        return OdometryRole(None, None, "")
    ruled = {e.topic: e.ruled_out() for e in found}
    kept = [e for e in found if ruled[e.topic] is None]
    others = "; ".join(f"{e.topic} not: {ruled[e.topic]}" for e in found if ruled[e.topic])
    if not kept:
        return OdometryRole(
            None,
            None,
            f"odometry: no wheel odometry among the Odometry topics ({others}); "
            "--data odometry_topic=TOPIC uses one",
        )
    best = max(e.score() for e in kept)
    top = [e for e in kept if e.score() == best]
    if len(top) > 1:
        listed = "; ".join(f"{e.topic} ({e.text()})" for e in top)
        raise InputError(
            f"{path}: several Odometry topics look like wheel odometry: {listed}; choose one "
            "with odometry_topic=TOPIC (or wheel_odometry=false)"
        )
    chosen = top[0]
    also = [e.topic for e in kept if e is not chosen]
    from_twist = _from_twist(chosen)
    return OdometryRole(
        chosen.topic,
        chosen,
        f"odometry: {chosen.topic} is the wheel odometry ({chosen.text()})"
        + (f"; also plausible, scored lower: {', '.join(also)}" if also else "")
        + (f"; {others}" if others else "")
        + _increments_text(from_twist)
        + "; --data odometry_topic=TOPIC overrides",
        from_twist,
    )


def _from_twist(evidence: PoseTopicEvidence) -> bool:
    """Increments from the twist where the pose stands still while the twist moves."""
    return evidence.twist_moves and not evidence.pose_moves


def _increments_text(from_twist: bool) -> str:
    return (
        "; increments from the twist times dt (its pose never moves)"
        if from_twist
        else "; increments from consecutive poses"
    )
