"""Numbers as people read them in JSON and CSV outputs: significant digits, no NaN."""

from __future__ import annotations

import math

__all__ = ["significant", "SIGNIFICANT_DIGITS"]

#: Significant digits written for measured and computed quantities. The solver's force
#: tolerance is 1e-8 of the load and image quantities carry 8-16 bits, so six digits keep
#: every figure that means something (-7.999999999999868 N is written -8.0).
SIGNIFICANT_DIGITS = 6


def significant(obj, digits: int = SIGNIFICANT_DIGITS):
    """``obj`` with every float rounded to ``digits`` significant digits (recursively
    through dicts, lists and tuples); NaN and infinities become None (JSON has neither)."""
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, float) or hasattr(obj, "dtype") and getattr(obj, "ndim", 1) == 0:
        x = float(obj)
        if not math.isfinite(x):
            return None
        return float(f"{x:.{digits}g}")
    if isinstance(obj, dict):
        return {k: significant(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [significant(v, digits) for v in obj]
    return obj
