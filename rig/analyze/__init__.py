"""``rig analyze``: the paper's models re-run on each run's measured plate motion, predictions beside the observed
overturns, and the Fig. 13 comparison (analytical against experimental COR per angle and body).

* `analyze_session` (`rig.analyze.session`): the entry point; returns a `SessionAnalysis` and writes the session
  file's ``analysis`` groups (`rig.analyze.store`), raw data untouched.
* `rig.analyze.transform`: measured plate-frame specific force → the models' (acc_h, acc_v), with its derivation.
* `rig.analyze.fig13`: the COR definition and the comparison rows.
"""

from .fig13 import Case, Fig13Row, fig13_rows, max_difference
from .results import Agreement, Prediction, RunAnalysis, SessionAnalysis, SkippedRun
from .session import MODELS, SOLVERS, analyze_run, analyze_session, observed_directions
from .store import SCHEMA, SessionBusyError
from .transform import DESCRIPTION, ModelInput, TransformError, measured_inputs, model_to_plate, plate_to_model

__all__ = [
    "DESCRIPTION",
    "MODELS",
    "SCHEMA",
    "SOLVERS",
    "Agreement",
    "Case",
    "Fig13Row",
    "ModelInput",
    "Prediction",
    "RunAnalysis",
    "SessionAnalysis",
    "SessionBusyError",
    "SkippedRun",
    "TransformError",
    "analyze_run",
    "analyze_session",
    "fig13_rows",
    "max_difference",
    "measured_inputs",
    "model_to_plate",
    "observed_directions",
    "plate_to_model",
]
