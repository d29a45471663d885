"""The stage registry: which module makes which product.

A stage is a module ``workflow.stages.<name>`` with ``NAME``, ``SECTIONS``,
``NEEDS``, ``PRODUCES`` and ``run(scene, inputs, out, log) -> dict``
(``docs/contracts.md`` §8). The registry below is plain data on purpose: the
pipeline imports a stage module only when the scene needs its product, so a
scene asking for the reduction check never imports the harmonic-balance code
(and a module with heavy imports costs nothing to the scenes that skip it).

Optional module attributes:

* ``CACHE = False`` — never cached; runs after all cached stages, straight
  into the run folder, so only for a terminal stage (the report, which shows
  this run's timings).
* ``NEEDS_ALL = True`` — receives every other product of the run, plus
  ``inputs["summary"]``: a JSON file with the run summary so far (the report).
* ``MPI = True`` — collective under ``mpirun``: every rank runs ``run`` (with
  the same ``out``, which only rank 0 may write to); without it a stage runs
  on rank 0 while the others wait (``workflow/pipeline.py``, ``workflow/mpi.py``).
"""
from __future__ import annotations

import importlib
from types import ModuleType

from workflow.errors import SceneError

#: product → name of the stage that makes it.
PRODUCERS: dict[str, str] = {
    "mesh": "geometry",
    "bundle": "assembly",
    "modes": "modes",
    "reduced": "reduction",
    "reduction_check": "reduction_check",
    "frf": "hb",
    "wear": "wear",
    "wear_map": "remap",
    "extreme": "extreme",
    "report": "report",
    "scaling": "scaling",
    "verification": "verification",
    "contact_convergence": "contact_convergence",
    "interface_scaling": "interface_scaling",
    "cyclic_modes": "cyclic_modes",
    "nonlinear_modes": "nonlinear_modes",
    "mistuning": "mistuning",
}

#: stage name → module path. Tests and plug-ins may register others here.
MODULES: dict[str, str] = {name: f"{__name__}.{name}" for name in PRODUCERS.values()}

_REQUIRED = ("NAME", "SECTIONS", "NEEDS", "PRODUCES", "run")


def producer(product: str) -> str:
    """Name of the stage that makes ``product``."""
    try:
        return PRODUCERS[product]
    except KeyError:
        raise SceneError(f"unknown product {product!r} (known: {', '.join(PRODUCERS)})") from None


def load(name: str) -> ModuleType:
    """Import stage ``name`` and check that it declares the stage contract.

    A stage module that does not exist yet is a :class:`SceneError` naming
    the stage (the scene asks for something this installation cannot make);
    an import error *inside* the module is a bug and keeps its traceback.
    """
    try:
        modname = MODULES[name]
    except KeyError:
        raise SceneError(f"unknown stage {name!r} (known: {', '.join(MODULES)})") from None
    try:
        module = importlib.import_module(modname)
    except ModuleNotFoundError as exc:
        if exc.name and (modname == exc.name or modname.startswith(exc.name + ".")):
            raise SceneError(f"stage {name!r} is not available in this installation (no module {modname})") from None
        raise
    missing = [a for a in _REQUIRED if not hasattr(module, a)]
    if missing:
        raise TypeError(f"stage module {modname} lacks {', '.join(missing)} (docs/contracts.md §8)")
    if module.NAME != name:
        raise TypeError(f"stage module {modname} declares NAME = {module.NAME!r}, registered as {name!r}")
    return module
