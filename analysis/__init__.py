"""Physics and statistics on arrays: bodies, the paper's models, solvers, studies, design equations.

Imports nothing else of this project. Units: SI inside; the public API takes accelerations in g
and angles in radians (docs/architecture.md §2, §7).
"""

from analysis.compiled_cache import configure as _configure_compiled_cache

_configure_compiled_cache()

from analysis.body import TABLE_I, TABLE_V, Body  # noqa: E402
from analysis.errors import AnalysisInputError  # noqa: E402
from analysis.simulate import SimulationResult, simulate  # noqa: E402
from analysis.thresholds import exceeds_threshold, uplift_thresholds  # noqa: E402

__all__ = [
    "TABLE_I",
    "TABLE_V",
    "AnalysisInputError",
    "Body",
    "SimulationResult",
    "exceeds_threshold",
    "simulate",
    "uplift_thresholds",
]
