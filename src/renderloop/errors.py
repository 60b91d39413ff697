"""The one exception type that means "the user gave us something we cannot use".

The CLI turns it into a single line on stderr and exit code 2; anything else that
escapes is a bug and keeps its traceback.
"""


class UserError(Exception):
    """Bad input: a config field, a file or a path. The message names it in one line."""


def field_path(loc: tuple[int | str, ...]) -> str:
    """A pydantic error location as `camera.rate_hz`; a key that is not one printable line is quoted (repr), so a
    user's key holding a newline cannot split the one-line message."""
    return ".".join(str(part) if str(part).isprintable() else repr(part) for part in loc)
