"""JSON text of values that may hold numpy scalars and arrays (the CLI's ``--json``, study file attributes)."""

from __future__ import annotations

import numpy as np


def json_default(o: object) -> object:
    """``json.dumps``'s ``default``: numpy integers → int, floats → float, arrays → lists; anything else refused."""
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
