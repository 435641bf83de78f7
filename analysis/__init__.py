"""Physics and statistics on arrays: bodies, the paper's models, solvers, studies, design equations.

Imports nothing else of this project. Units: SI inside; the public API takes accelerations in g
and angles in radians (ARCHITECTURE §2, §7).
"""

from analysis.body import TABLE_I, TABLE_V, Body
from analysis.errors import AnalysisInputError
from analysis.simulate import SimulationResult, simulate
from analysis.thresholds import exceeds_threshold, uplift_thresholds

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
