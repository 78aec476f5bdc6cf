"""How a number is written in every output: the terminal tables, the HTML report and the
comparison of two campaigns."""

from __future__ import annotations

import math


def number_text(x, fmt: str, missing: str = "-") -> str:
    """*x* formatted with *fmt*, or *missing* for None, NaN, inf or a non-number (every
    table, the HTML report and the comparison write their numbers with it)."""
    try:
        x = float(x)
    except (TypeError, ValueError):
        return missing
    return missing if not math.isfinite(x) else format(x, fmt)
