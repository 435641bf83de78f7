"""Physics and statistics on arrays: bodies, the paper's models, solvers, studies, design equations.

Imports nothing else of this project. Units: SI inside; the public API takes accelerations in g
and angles in radians (docs/architecture.md §2, §7).
"""

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

from analysis.compiled_cache import configure as _configure_compiled_cache

_configure_compiled_cache()

from analysis.body import TABLE_I, TABLE_V, Body  # noqa: E402
from analysis.errors import AnalysisInputError  # noqa: E402

if TYPE_CHECKING:
    from analysis.simulate import SimulationResult, simulate
    from analysis.thresholds import exceeds_threshold, uplift_thresholds

#: Names imported from their module on first use (numpy, scipy and numba only when a model is needed).
_LAZY = {
    "SimulationResult": "analysis.simulate",
    "simulate": "analysis.simulate",
    "exceeds_threshold": "analysis.thresholds",
    "uplift_thresholds": "analysis.thresholds",
}


def __getattr__(name: str) -> Any:
    """``analysis.simulate`` & co. on first use (PEP 562), so that ``import analysis.body`` stays light."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'analysis' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


class _Package(types.ModuleType):
    """The package module: when the submodule ``analysis.simulate`` is first imported (by anyone), Python binds it
    as the package attribute ``simulate``; the function of that name is kept there instead, as it always was."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "simulate" and isinstance(value, types.ModuleType):
            value = value.simulate
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package

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
