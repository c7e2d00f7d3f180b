"""``PassReport``: what a pass over a sequence's stream found, typed, on the ``Sequence``.

Some sources learn things only by reading their stream: a bag's reader counts the messages
it skipped or trimmed, a front end settles its settings (KISS-ICP's range and voxel) and
its statistics (corner re-observations, 2-D laser corners), wheel odometry counts the
increments it composed. The stream records them here at the end of each complete pass,
so the report is empty before the first pass and complete after one; a later pass finds
the same (the front ends are cached, a warning is kept once), so it changes nothing. A
pass that stops early records nothing.

The workbench prints the warnings with the loader's (``Sequence.all_warnings``) and writes
the figures into the run's description of the source (``Sequence.description``:
``config.yaml``'s ``dataset_metadata``), where nothing else reads them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any


@dataclass
class PassReport:
    """What the last complete pass over the stream found (module docstring).

    Attributes:
        warnings: what the pass skipped, trimmed or doubted, one line each, each kept once
            however often the stream is read (skipped messages, the front end's heading,
            warm-up and IMU-deskew warnings).
        figures: the pass's figures for the run's description, by the key they are written
            under (JSON-ready mappings, e.g. ``kiss_icp``: the KISS-ICP settings used;
            ``corner_reobservation``; ``odometry_counts``; ``laser_corners``, ``corners``:
            the 2-D laser front end's summary). The loader names the keys at load (empty
            mappings), so the description holds them whether or not a pass has run.
        passes: complete passes so far.
    """

    warnings: list[str] = field(default_factory=list)
    figures: dict[str, dict[str, Any]] = field(default_factory=dict)
    passes: int = 0

    @classmethod
    def expecting(cls, *keys: str) -> PassReport:
        """An empty report whose passes will fill the figures under ``keys``."""
        return cls(figures={key: {} for key in keys})

    def record(self, warnings: Iterable[str] = (), **figures: Mapping[str, Any]) -> None:
        """The end of a complete pass: its warnings (those not yet listed) and its figures
        (each updating the mapping under its key)."""
        for line in warnings:
            if line not in self.warnings:
                self.warnings.append(line)
        for key, values in figures.items():
            self.figures.setdefault(key, {}).update(values)
        self.passes += 1
