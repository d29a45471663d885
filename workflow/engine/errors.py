"""The errors the engine raises for what a user can cause; the CLI prints each as one line.

Every error a user can cause (a bad option or bundle, a solver that cannot
converge) is a :class:`BladewearError`; the application adds its own
(geometry) in :mod:`workflow.errors`. Anything else is a bug and
keeps its traceback.
"""


class BladewearError(Exception):
    """Base class of errors caused by input or by a physical impossibility."""


class SceneError(BladewearError):
    """An option out of range or of the wrong type (from a scene, or from Python)."""


class BundleError(BladewearError):
    """A model bundle or reduced model with missing parts or mismatched sizes."""


class SolverError(BladewearError):
    """A solver that diverged or stalled; the message carries the diagnosis."""


class OutputError(BladewearError):
    """An output file or folder that cannot be written (permissions, disk full)."""
