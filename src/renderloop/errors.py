"""The one exception type that means "the user gave us something we cannot use".

The CLI turns it into a single line on stderr and exit code 2; anything else that
escapes is a bug and keeps its traceback.
"""

from __future__ import annotations

import difflib
import typing
from collections.abc import Iterable

from pydantic import BaseModel, ValidationError


class UserError(ValueError):
    """Bad input: a config field, a file or a path. The message names it in one line.

    A ValueError, so that code using the Python API (`renderloop.Simulation`) can catch bad
    arguments the way Python code does, with the sentence the CLI would print."""


def field_path(loc: tuple[int | str, ...]) -> str:
    """A pydantic error location as `camera.rate_hz`; a key that is not one printable line is quoted (repr), so a
    user's key holding a newline cannot split the one-line message."""
    return ".".join(str(part) if str(part).isprintable() else repr(part) for part in loc)


def closest(word: str, choices: Iterable[str]) -> str | None:
    """The one of `choices` a mistyped `word` most likely meant, or None when none is close."""
    found = difflib.get_close_matches(str(word), list(choices), n=1, cutoff=0.6)
    return found[0] if found else None


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """`; did you mean X?` for the closest of `choices`, or nothing: the tail of a one-line refusal."""
    match = closest(word, choices)
    return f"; did you mean {match}?" if match is not None else ""


def _models_in(annotation: object) -> list[type[BaseModel]]:
    """The pydantic models an annotation holds: itself, or inside an Optional, a list, a tuple, a dict's values."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is typing.Annotated:
        args = args[:1]
    return [model for arg in args for model in _models_in(arg)]


def _models_at(model: type[BaseModel], loc: tuple[int | str, ...]) -> list[type[BaseModel]]:
    """The models at `loc` below `model`: a list index or a dict key (a part no field has) keeps the models the
    container holds."""
    models = [model]
    for part in loc:
        named = [current for current in models if isinstance(part, str) and part in current.model_fields]
        if named:
            models = [inner for current in named for inner in _models_in(current.model_fields[part].annotation)]
    return models


def _literals_in(annotation: object) -> list[str]:
    """The names a `Literal` annotation allows, inside an Optional, a tuple or a list of them too."""
    if typing.get_origin(annotation) is typing.Literal:
        return [value for value in typing.get_args(annotation) if isinstance(value, str)]
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) is typing.Annotated:
        args = args[:1]
    return [value for arg in args for value in _literals_in(arg)]


def _names_allowed(model: type[BaseModel], loc: tuple[int | str, ...]) -> list[str]:
    """The names the choice field at `loc` below `model` allows, or none."""
    *parent, name = loc
    if isinstance(name, int):  # an item of a tuple or list of names: the field that holds them
        return _names_allowed(model, tuple(parent)) if parent else []
    return [value for current in _models_at(model, tuple(parent)) if name in current.model_fields
            for value in _literals_in(current.model_fields[name].annotation)]


def problem(error: ValidationError, model: type[BaseModel] | None = None) -> str:
    """The first thing wrong in a pydantic validation, as `field.path: message` (no path for a check across fields).
    With the `model` validated, a key no field has, or a name a choice does not allow, names the closest right one."""
    first = error.errors()[0]
    field = field_path(first["loc"])
    if first["type"] == "extra_forbidden":
        message = "unknown field"
        *parent, key = first["loc"] or ("",)
        if model is not None and isinstance(key, str):
            fields = {name for current in _models_at(model, tuple(parent)) for name in current.model_fields}
            match = closest(key, sorted(fields))
            if match is not None:
                message += f"; did you mean {field_path((*parent, match))}?"
    else:
        message = first["msg"].removeprefix("Value error, ")
        if first["type"] == "literal_error" and model is not None and isinstance(first.get("input"), str):
            message += did_you_mean(first["input"], _names_allowed(model, tuple(first["loc"])))
    return f"{field}: {message}" if field else message
