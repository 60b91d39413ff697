"""The one exception type that means "the user gave us something we cannot use".

The CLI turns it into a single line on stderr and exit code 2; anything else that
escapes is a bug and keeps its traceback.
"""

from pydantic import ValidationError


class UserError(ValueError):
    """Bad input: a config field, a file or a path. The message names it in one line.

    A ValueError, so that code using the Python API (`renderloop.Simulation`) can catch bad
    arguments the way Python code does, with the sentence the CLI would print."""


def field_path(loc: tuple[int | str, ...]) -> str:
    """A pydantic error location as `camera.rate_hz`; a key that is not one printable line is quoted (repr), so a
    user's key holding a newline cannot split the one-line message."""
    return ".".join(str(part) if str(part).isprintable() else repr(part) for part in loc)


def problem(error: ValidationError) -> str:
    """The first thing wrong in a pydantic validation, as `field.path: message` (no path for a check across fields)."""
    first = error.errors()[0]
    message = "unknown field" if first["type"] == "extra_forbidden" else first["msg"].removeprefix("Value error, ")
    field = field_path(first["loc"])
    return f"{field}: {message}" if field else message
