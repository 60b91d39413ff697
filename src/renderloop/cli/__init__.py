"""The `renderloop` command: one verb per pipeline stage, plus `run` for all of them.

Bad input ends in one line on stderr and exit code 2 (UserError); an operating-system
failure such as a full disk or a read-only directory in one line and exit code 1.
"""

from __future__ import annotations

import sys
from pathlib import Path

from typer.exceptions import Abort as TyperAbort
from typer.exceptions import TyperException

from renderloop.cli import detector, stages  # noqa: F401  (importing them adds their verbs to the app)
from renderloop.cli.common import app
from renderloop.errors import UserError
from renderloop.io.atomic import final_path

__all__ = ["app", "main"]


def _one_line(message: str) -> str:
    """`message` with every character that is not printable (a newline or escape in a path) written as its Python
    escape, as `errors.field_path` quotes a key: an error is one line whatever the user's paths hold."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)


def _error(message: str, code: int) -> None:
    print(f"renderloop: error: {_one_line(message)}", file=sys.stderr)
    sys.exit(code)


def main() -> None:
    try:
        code = app(standalone_mode=False)  # click's usage errors come here instead of a usage block
    except TyperException as error:  # an option out of range, a missing one: bad input like any other
        message = " ".join(error.format_message().split())
        if message:  # empty after the help that no arguments print
            _error(message, 2)
        sys.exit(2)
    except TyperAbort:  # Ctrl-C
        sys.exit(130)
    except UserError as error:
        _error(str(error), 2)
    except OSError as error:  # the machine, not the input: a full disk, a directory we may not write
        where = f"{final_path(Path(error.filename))}: " if error.filename else ""
        _error(f"{where}{error.strerror or error}", 1)
    sys.exit(code if isinstance(code, int) else 0)
