"""Error types that the CLI turns into one line naming the problem.

Every error a user can cause (bad scene, bad bundle, bad geometry, a solver
that cannot converge) is raised as a subclass of :class:`BladewearError`; the
CLI prints ``error: <message>`` and exits with status 2. Anything else is a
bug and keeps its traceback.
"""


class BladewearError(Exception):
    """Base class of errors caused by input or by a physical impossibility."""


class SceneError(BladewearError):
    """Malformed scene, unknown key, wrong type or value out of range."""


class GeometryError(BladewearError):
    """Geometry parameters that cannot make a valid sector, or a gmsh failure."""


class BundleError(BladewearError):
    """A model bundle with missing files or mismatched sizes."""


class SolverError(BladewearError):
    """A solver that diverged or stalled; the message carries the diagnosis."""


class OutputError(BladewearError):
    """An output folder that cannot be written (permissions, disk full)."""
