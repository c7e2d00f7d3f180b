"""Wrong tracks from jumps: which later jump undoes which jump away (``_reverse``,
``_reversal``) and the nested pairs that bound a ``wrong_track`` (``_pair``)."""

from __future__ import annotations

import math

import numpy as np

from datasets.truth_quality.jumps import _Jump
from datasets.truth_quality.settings import TruthQualitySettings


def _reverse(away: np.ndarray, back: np.ndarray, angular: bool) -> tuple[float, float]:
    """How well ``back`` reverses ``away``: (cosine between ``-away`` and ``back``, the
    remainder ``|away + back| / (|away| + |back|)``, 0 when it undoes it exactly). For
    rotations ``back`` is taken as the equivalent rotation vector (or heading) nearest to
    ``-away``, so a flip by pi is its own reverse."""
    away = np.asarray(away, dtype=float)
    candidates = [np.asarray(back, dtype=float)]
    if angular:
        size = float(np.linalg.norm(back))
        if size > 0:
            candidates.append(candidates[0] * (1.0 - 2.0 * math.pi / size))
    best = (-1.0, 1.0)
    for candidate in candidates:
        norms = float(np.linalg.norm(away) * np.linalg.norm(candidate))
        if norms <= 0:
            continue
        cosine = float(np.dot(-away, candidate)) / norms
        total = float(np.linalg.norm(away) + np.linalg.norm(candidate))
        remainder = float(np.linalg.norm(away + candidate)) / total
        if cosine > best[0]:
            best = (cosine, remainder)
    return best


def _reversal(away: _Jump, back: _Jump, min_cosine: float) -> float | None:
    """The remainder (0: exact) with which ``back`` undoes ``away``, or None when it does
    not: some part significant in both (position, rotation) must point back within
    ``acos(min_cosine)`` of the reverse. One part is enough: a heading failure's small
    position steps at its edges turn with the robot, its heading offset does not."""
    remainders = []
    if away.position_significant and back.position_significant:
        cosine, remainder = _reverse(away.position, back.position, angular=False)
        if cosine >= min_cosine:
            remainders.append(remainder)
    if away.rotation_significant and back.rotation_significant:
        cosine, remainder = _reverse(away.rotation, back.rotation, angular=True)
        if cosine >= min_cosine:
            remainders.append(remainder)
    return min(remainders) if remainders else None


def _pair(
    jumps: list[_Jump], t: np.ndarray, settings: TruthQualitySettings
) -> tuple[list[tuple[_Jump, _Jump]], list[_Jump]]:
    """Pairs (away, back) of neighbouring jumps where the second undoes the first, and the
    jumps left alone. A pair leaves the list, so its neighbours become neighbours: pairs
    nest and never cross. Exact pairs (remainder within ``pair_exact_remainder``) go first,
    shortest first, then inexact ones, shortest first: a heading failure undoes its entry
    exactly while a jump next to it may point back by chance, and a drifting position
    offset undoes its entry only roughly, so among rough pairs the innermost is likeliest."""
    remaining = list(range(len(jumps)))
    pairs: list[tuple[_Jump, _Jump]] = []
    longest = settings.wrong_track_max_fraction * float(t[-1] - t[0])
    keys: dict[tuple[int, int], tuple[bool, float] | None] = {}

    def key(a: int, b: int) -> tuple[bool, float] | None:
        # cached: only the pair that a removal makes neighbours is new each round
        if (a, b) not in keys:
            away, back = jumps[a], jumps[b]
            span = float(t[back.last] - t[away.first + 1])
            remainder = _reversal(away, back, settings.pair_min_cosine)
            keys[(a, b)] = (
                None
                if span > longest or remainder is None
                else (remainder > settings.pair_exact_remainder, span)
            )
        return keys[(a, b)]

    while True:
        best, best_key = None, (True, math.inf)
        for k in range(len(remaining) - 1):
            found = key(remaining[k], remaining[k + 1])
            if found is not None and found < best_key:
                best, best_key = k, found
        if best is None:
            return pairs, [jumps[index] for index in remaining]
        pairs.append((jumps[remaining[best]], jumps[remaining[best + 1]]))
        del remaining[best : best + 2]
