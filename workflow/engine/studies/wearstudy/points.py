"""The operating points a wear problem stands for: a held tip amplitude's vibration at its load
(:func:`_held_amplitude`), a mission's points, and a problem of the same kind rebuilt from them."""
from __future__ import annotations

import numpy as np

from workflow.engine.errors import SceneError
from workflow.engine.studies.wearstudy.options import WearOptions


def _held(wp) -> bool:
    """Whether ``wp`` holds a tip amplitude (:class:`~workflow.engine.studies.amplitude.AmplitudeProblem`:
    its unknowns end with the load scale)."""
    return getattr(wp, "target", None) is not None


def _points(wp, omega, x) -> list:
    """[(WearProblem, ω [rad/s], its unknowns)] of each operating point of ``wp``: a
    :class:`~workflow.engine.studies.operating.MissionProblem`'s points, else ``wp`` itself at ω."""
    if _held(wp):                                     # the vibration at its load
        wp.set_scale(x[-1])
        return [(wp.wp, omega, np.asarray(x)[:-1])]
    if getattr(wp, "members", None) is None:
        return [(wp, omega, x)]
    return list(zip(wp.members, wp.omegas, wp.split(x)))


def _like(wp, problems: list, xs: list):
    """(problem, unknowns) of the same kind as ``wp`` from its points' modified problems and
    solutions (:func:`_points`): a mission of them, or the one."""
    if _held(wp):
        return wp.like(problems[0], xs[0])
    if getattr(wp, "members", None) is None:
        return problems[0], xs[0]
    from workflow.engine.studies.operating import MissionProblem

    return MissionProblem(problems, wp.shares, wp.omegas, wp.headline), np.concatenate(xs)


def _held_amplitude(rc, wp, base, omega: float, opt: WearOptions, point: dict, log, scale: float = 1.0):
    """(:class:`~workflow.engine.studies.amplitude.AmplitudeProblem`, its unworn SolveResult with
    the unknowns [x; s]) of ``wp`` with the tip held at ``opt.tip_amplitude_m`` (0: the amplitude
    of the unworn vibration ``base`` under the load as built), started from ``base`` under
    ``scale`` × that load; records ``point["control"]``."""
    from workflow.engine.studies.amplitude import hold

    if point["kind"] in ("resonance", "mission"):
        raise SceneError(f"wear.control = \"amplitude\" with wear.operating_point = \"{point['kind']}\": a held "
                         "amplitude wears at one frequency (\"frequency\" or \"detuning\")")
    ap, res, _ = hold(rc, wp, base.x, omega, max(float(opt.tip_amplitude_m), 0.0), tol=opt.tol,
                      maxiter=opt.max_iterations, scale=scale)
    target = ap.target
    point["control"] = {"kind": "amplitude", "tip_amplitude_m": target, "load_scale_new": float(res.x[-1])}
    if log is not None:
        log.info(f"tip held at {target:.4g} m: the load × {res.x[-1]:.4g} on the new blade")
    return ap, res
