"""Numeric CSV tables with a header row: written atomically, read back with the header and every number checked."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from renderloop.errors import UserError
from renderloop.io.atomic import write_text
from renderloop.io.bounded import FINITE, Bound, check_columns


def write_csv(path: Path, header: list[str], table: np.ndarray, fmt: str | list[str] = "%.6f") -> None:
    buffer = io.StringIO()
    positive_zeros = np.asarray(table) + 0.0  # -0.0 + 0.0 is 0.0: no "-0.000000" in the files
    np.savetxt(buffer, positive_zeros, delimiter=",", fmt=fmt, header=",".join(header), comments="")
    write_text(path, buffer.getvalue())


def row_name(index: int) -> str:
    """How a message names the table's row `index` (0: the first under the header)."""
    return f"row {index + 1}"


def read_csv(path: Path, header: list[str], bounds: Sequence[Bound] | None = None) -> np.ndarray:
    """The table under `header`; a missing, foreign, truncated or non-numeric file is a one-line UserError, and
    so is a number that is NaN, infinite or outside its column's bound (`bounds`, one per column; without them,
    every number finite)."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as handle:
            first = handle.readline().strip()
            if first.split(",") != header:
                raise UserError(f"{path}: header is not {','.join(header)}")
            table = np.loadtxt(handle, delimiter=",", ndmin=2, comments=None)
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except UserError:
        raise
    except (ValueError, UnicodeDecodeError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        raise UserError(f"{path}: not a numeric table ({reason})") from None
    if table.shape[0] == 0 or table.shape[1] != len(header):
        raise UserError(f"{path}: expected rows of {len(header)} numbers, found {table.shape[1] if table.size else 0}")
    check_columns(str(path), table, header, [FINITE] * len(header) if bounds is None else bounds, row_name)
    return table
