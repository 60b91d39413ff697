"""Seed lists as people type them: `0-19`, `3`, `0,4,7-9`."""

from __future__ import annotations

import re

from renderloop.errors import UserError

MAX_SEEDS = 10_000
_PART = re.compile(r"^(\d+)(?:-(\d+))?$")


def parse_seeds(text: str) -> list[int]:
    """Distinct seeds in the order given; a malformed, reversed or empty list is a one-line UserError."""
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        match = _PART.match(part)
        if not match:
            raise UserError(f"--seeds {text!r}: {part!r} is not a seed or a range like 0-19")
        first, last = int(match[1]), int(match[2] if match[2] is not None else match[1])
        if last < first:
            raise UserError(f"--seeds {text!r}: the range {part} runs backwards")
        if last - first + 1 + len(seeds) > MAX_SEEDS:
            raise UserError(f"--seeds {text!r}: more than {MAX_SEEDS} runs")
        seeds.extend(seed for seed in range(first, last + 1) if seed not in seeds)
    return seeds
