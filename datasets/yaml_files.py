"""The one way the workbench reads YAML a user hands it: ``--config`` files, suite files, a
run folder's ``config.yaml`` and ``--set``/``--data`` values.

PyYAML's ``safe_load`` runs no code, but it still lets a file do three things a user never
means and rarely sees:

- a key written twice in one mapping keeps the last value silently (a ``--config`` with two
  ``gate_probability`` lines runs with the second);
- anchors and aliases (``&a``, ``*a``) let a few hundred bytes stand for gigabytes once the
  value is walked (a 385-byte suite of nested aliases became 157 MB and minutes of work);
- the file can be of any size and any encoding.

``read_yaml_file`` refuses all of these with an ``InputError`` naming the file and line:
files over ``MAX_YAML_BYTES`` (1 MiB, far above any configuration or suite the workbench
writes, a few KiB) are refused before parsing, the text must be UTF-8, and anchors, aliases
and duplicate keys are errors. ``yaml_text`` applies the same rules to a string.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from datasets.errors import InputError

MAX_YAML_BYTES = 1 << 20
"""1 MiB: the largest YAML file read (checked before parsing)."""


# libyaml's parser where PyYAML was built with it: it reads a 1 MiB file several times
# faster than the pure-Python one and stops nesting at depth 1000 by itself
_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _StrictLoader(_SafeLoader):
    """``SafeLoader`` that refuses duplicate keys (module docstring); ``yaml_text`` refuses
    anchors and aliases before it composes anything."""

    source = "YAML"

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            first_line: dict[Any, int] = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    seen = key in first_line
                except TypeError:  # an unhashable key: PyYAML's own error says so
                    continue
                line = key_node.start_mark.line + 1
                if seen:
                    raise InputError(
                        f"{self.source}:{line}: key '{key}' appears twice in one mapping (first "
                        f"on line {first_line[key]}); YAML would keep the last value silently, "
                        "so write it once"
                    )
                first_line[key] = line
        return super().construct_mapping(node, deep)


def _refuse_anchors(text: str, source: str) -> None:
    """``InputError`` at the first anchor or alias, from the parser's events (libyaml's
    parser composes in C, where no hook sees them); nothing is composed or expanded yet."""
    for event in yaml.parse(text, Loader=_SafeLoader):
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise InputError(
                f"{source}:{event.start_mark.line + 1}: YAML anchors and aliases (&name, "
                "*name) are not accepted: write the value out in full (aliases let a small "
                "file expand without bound)"
            )


def yaml_text(text: str, source: str) -> Any:
    """The value of one YAML document ``text``; ``InputError`` naming ``source`` and the
    line for invalid YAML, anchors, aliases, duplicate keys or nesting too deep."""
    loader = _StrictLoader(text)
    loader.source = source
    try:
        _refuse_anchors(text, source)
        return loader.get_single_data()
    except InputError:
        raise
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        where = f"{source}:{mark.line + 1}" if mark is not None else source
        problem = error.problem or error.context or type(error).__name__
        raise InputError(f"{where}: not valid YAML ({problem})") from None
    except yaml.YAMLError as error:
        raise InputError(f"{source}: not valid YAML ({error})") from None
    except RecursionError:
        raise InputError(f"{source}: not valid YAML (nested too deeply)") from None
    except ValueError as error:  # a scalar PyYAML cannot convert (a 5000-digit integer)
        raise InputError(f"{source}: not valid YAML ({error})") from None
    finally:
        loader.dispose()


def read_yaml_file(path: str | Path) -> Any:
    """The value of the YAML file at ``path`` (module docstring: at most ``MAX_YAML_BYTES``,
    1 MiB, UTF-8, no anchors, aliases or duplicate keys); ``InputError`` naming the file and
    line otherwise. An unreadable file raises the ``OSError``, which names it."""
    path = Path(path)
    with path.open("rb") as stream:
        data = stream.read(MAX_YAML_BYTES + 1)  # never more, whatever the file's size
    if len(data) > MAX_YAML_BYTES:
        raise InputError(
            f"{path}: larger than {MAX_YAML_BYTES >> 20} MiB, the limit for a YAML file the "
            "workbench reads (a configuration or suite is a few KiB)"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        raise InputError(
            f"{path}:{line}: not UTF-8 text (byte 0x{data[error.start]:02x}); a YAML file is UTF-8"
        ) from None
    return yaml_text(text, str(path))
