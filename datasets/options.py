"""Parsing ``key=value`` options (``--data``, ``--set``) into pydantic models.

Values are read as YAML scalars (``true``, ``3``, ``0.5``, ``[1, 2]``) and validated by the
model, so every loader and estimator gets typed options and one style of error message.
"""

from __future__ import annotations

from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from datasets.errors import InputError

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
    """A ``key=value`` right-hand side as a YAML scalar or list (plain string if not YAML)."""
    try:
        return yaml.safe_load(text) if text != "" else ""
    except yaml.YAMLError:
        return text


def build_model(model: type[ModelT], values: dict[str, object], context: str) -> ModelT:
    """Validate ``values`` against ``model``; ``InputError`` naming ``context`` and the key.

    The model should forbid extra keys (``model_config = ConfigDict(extra="forbid")``) so a
    misspelt key is an error, not a silent default.
    """
    try:
        return model.model_validate(values)
    except ValidationError as error:
        problems = "; ".join(
            f"{'.'.join(str(part) for part in item['loc']) or '(config)'}: {item['msg']}"
            for item in error.errors()
        )
        known = ", ".join(model.model_fields)
        raise InputError(f"{context}: {problems} (known keys: {known})") from None


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
