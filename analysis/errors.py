"""The one error type of the analysis package: bad input, stated plainly."""


class AnalysisInputError(ValueError):
    """Raised for input the models cannot run on; the message says what is wrong and where."""
