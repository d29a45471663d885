"""Error types that the CLI turns into one line naming the problem.

Every error a user can cause (bad scene, bad bundle, bad geometry, a solver
that cannot converge) is raised as a subclass of :class:`BladewearError`; the
CLI prints ``error: <message>`` and exits with status 2. Anything else is a
bug and keeps its traceback. The engine's errors are defined with the engine
(:mod:`workflow.engine.errors`), which imports nothing of the application.
"""
from workflow.engine.errors import BladewearError, BundleError, OutputError, SceneError, SolverError

__all__ = ["BladewearError", "BundleError", "GeometryError", "OutputError", "SceneError", "SolverError"]


class GeometryError(BladewearError):
    """Geometry parameters that cannot make a valid sector, or a gmsh failure."""
