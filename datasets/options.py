"""Parsing ``key=value`` options (``--data``, ``--set``) into pydantic models.

Values are read as YAML scalars (``true``, ``3``, ``0.5``, ``[1, 2]``) and validated by the
model, so every loader and estimator gets typed options and one style of error message.
Dotted keys address nested models (``kiss.voxel_size_m=0.5``, ``nest_dotted``).
"""

from __future__ import annotations

from typing import TypeVar

from pydantic import BaseModel, ValidationError

from datasets.errors import InputError, did_you_mean
from datasets.yaml_files import yaml_text

ModelT = TypeVar("ModelT", bound=BaseModel)


def parse_assignments(assignments: list[str] | tuple[str, ...], flag: str) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``; ``InputError`` naming ``flag`` otherwise."""
    parsed: dict[str, str] = {}
    for assignment in assignments:
        key, separator, value = assignment.partition("=")
        if not separator or not key.strip():
            raise InputError(f"{flag} expects key=value, got '{assignment}'")
        parsed[key.strip()] = value.strip()
    return parsed


def yaml_value(text: str) -> object:
    """A ``key=value`` right-hand side as a YAML scalar or list (plain string if not YAML).

    Read by ``datasets.yaml_files`` rules: text with an anchor or alias (``&a``, ``*a``)
    or a repeated key stays the plain string, so a value never expands beyond what was typed.
    """
    try:
        return yaml_text(text, "value") if text != "" else ""
    except InputError:
        return text


def nest_dotted(options: dict[str, str]) -> dict[str, object]:
    """``{"kiss.voxel_size_m": "0.5"}`` -> ``{"kiss": {"voxel_size_m": 0.5}}`` (YAML values),
    at any depth (``laser.corner.min_range_m``)."""
    nested: dict[str, object] = {}
    for key, value in options.items():
        *heads, last = key.split(".")
        group = nested
        for depth, head in enumerate(heads):
            group.setdefault(head, {})
            if not isinstance(group[head], dict):
                raise InputError(
                    f"--data {key}: '{'.'.join(heads[: depth + 1])}' is not a group of options"
                )
            group = group[head]  # type: ignore[assignment]
        group[last] = yaml_value(value)
    return nested


def _problem(item: dict) -> str:
    """One pydantic error as ``key: what is wrong, got VALUE`` (the value when there was one
    to show: not for a missing or unknown key, whose name says it all)."""
    key = ".".join(str(part) for part in item["loc"]) or "(config)"
    text = f"{key}: {item['msg']}"
    if item["loc"] and item["type"] not in ("missing", "extra_forbidden"):
        shown = repr(item.get("input"))
        text += f", got {shown if len(shown) <= 60 else shown[:57] + '...'}"
    return text


def build_model(model: type[ModelT], values: dict[str, object], context: str) -> ModelT:
    """Validate ``values`` against ``model``; ``InputError`` naming ``context`` and the key.

    The model should forbid extra keys (``model_config = ConfigDict(extra="forbid")``) so a
    misspelt key is an error, not a silent default.
    """
    try:
        return model.model_validate(values)
    except ValidationError as error:
        items = error.errors()
        unknown = [item for item in items if item["type"] == "extra_forbidden"]
        fields = list(model.model_fields)
        problems = "; ".join(
            _problem(item)
            + (did_you_mean(str(item["loc"][0]), fields) if item in unknown and item["loc"] else "")
            for item in items
        )
        # the known keys help a misspelt key; a bad value of a right key needs only itself
        known = f" (known keys: {', '.join(fields)})" if unknown else ""
        raise InputError(f"{context}: {problems}{known}") from None


def parse_options(model: type[ModelT], options: dict[str, str], context: str) -> ModelT:
    """``--data``/``--set`` strings -> validated model."""
    return build_model(model, {key: yaml_value(value) for key, value in options.items()}, context)


def describe_model(model: type[BaseModel]) -> list[str]:
    """One line per field: ``name (type, default): description`` for ``--verbose`` listings."""
    lines = []
    for name, info in model.model_fields.items():
        annotation = getattr(info.annotation, "__name__", str(info.annotation))
        if info.default_factory is not None:
            default = (
                "as listed below"
                if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)
                else repr(info.default_factory())
            )
        elif info.is_required():
            default = "required"
        else:
            default = repr(info.default)
        lines.append(
            f"{name} ({annotation}, default {default}): {info.description or ''}".rstrip(": ")
        )
    return lines
