"""Wear at a held tip amplitude (``wear.control = "amplitude"``, issue 48).

Under a fixed force at a fixed frequency the worn steady state is set by how far wear moves the
friction-damped resonance away from the forcing: next to a resonance the worn depth moves as
d ln W / d ln f ≈ −330 (quick sector, first tied resonance), and every model or contact mesh
whose resonance sits 1e-4 elsewhere wears differently. Held at a tip amplitude instead — the
blade vibrating at the level a strain gauge or tip timing reads, the force whatever it takes —
the interface's slip is set by the deflection shape, which next to a resonance is the mode's,
and the worn state is the partial-slip problem of an imposed motion (the slip zone wears until
it unloads: Ciavarella & Hills 1999, the `mdr` reference of docs/wear.md).

:class:`AmplitudeProblem` is a :class:`~workflow.engine.wear.WearProblem` with one more
unknown, the scale s of the dynamic load (harmonics ≥ 1 of F_r; the static preload stays), and
one more equation, ‖o₁(x, s)‖ = A: o₁ the first harmonic of the observed DOFs (the tip),
affine in the relative harmonics and in s (:func:`tip_map`). The wear marches take it for one
problem with the unknowns ``[x; s]``: J formed and bordered, or matrix-free, one structured
GMRES on the bordered system (:class:`Border`, :mod:`workflow.engine.wear.structured`,
:meth:`workflow.engine.linsolve.StructuredSolve.solve`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workflow.engine import fourier
from workflow.engine.errors import SceneError
from workflow.engine.wear import WearProblem, WearState

#: Steps of the continuation in the held amplitude when Newton's jump to it fails
#: (:meth:`AmplitudeProblem._continued`): equal steps of ln A from the start's amplitude.
CONTINUATION_STEPS = 4
#: Halvings of a failed continuation step before :meth:`AmplitudeProblem.start` gives up.
CONTINUATION_HALVINGS = 4


def tip_map(rc, omega: float) -> tuple[np.ndarray, np.ndarray]:
    """(C (n_obs, 3p), d (n_obs,)) complex: the observed DOFs' first harmonic is
    ``o₁ = C U₁ + s d`` [m] for relative first harmonics U₁ (3p,) [m] and the load scale s
    (:func:`workflow.engine.condense.recover` at ω [rad/s], which is affine in both: the tied
    remainder's response to U₁ and to the load). Formed by the coordinates' own ``tip_map`` where
    they have one (the whole disk's: :meth:`reduction.mistuned.WholeDiskCoordinates.tip_map`), else
    through their tied basis (:func:`workflow.engine.condense.recover_map`), else from 3p + 1 recoveries."""
    from workflow.engine.condense import recover, recover_map

    if hasattr(rc, "tip_map"):
        return rc.tip_map(omega)
    formed = recover_map(rc, omega, 1)
    if formed is not None:
        return formed
    p3 = rc.n_rel
    Ur = np.zeros((2, p3), dtype=complex)
    d = recover(rc, omega, Ur)[1]
    C = np.empty((d.size, p3), dtype=complex)
    for k in range(p3):
        Ur[1, k] = 1.0
        C[:, k] = recover(rc, omega, Ur)[1] - d
        Ur[1, k] = 0.0
    return C, d


def hold(rc, wp: WearProblem, x, omega: float, target: float, *, tol: float, maxiter: int,
         blades: int = 1, scale: float = 1.0):
    """Hold a tip of ``wp``'s model at ``target`` [m] (0: its amplitude in the vibration x under
    ``scale`` × the unit load, at ω [rad/s]): the observed DOFs split into ``blades`` equal
    groups (a whole disk's blades; 1: one tip), the group vibrating most in x held.
    Returns (:class:`AmplitudeProblem`, its SolveResult of ``[x; s]``, the group held);
    SceneError without observed DOFs, SolverError where the held vibration does not solve."""
    from workflow.engine.errors import SolverError

    C, d = tip_map(rc, omega)
    m = C.shape[0] // int(blades)
    if m == 0:
        raise SceneError("wear.control = \"amplitude\": the model observes no DOF (no tip to hold)")
    o = (C @ wp.hb.harmonics(x)[1] + scale * d).reshape(int(blades), m)
    b = int(np.argmax(np.linalg.norm(o, axis=1)))
    target = float(target) or float(np.linalg.norm(o[b]))
    rows = slice(b * m, (b + 1) * m)
    ap = AmplitudeProblem(wp, (C[rows], d[rows]), target)
    res = ap.start(x, tol=tol, maxiter=maxiter, scale=scale)
    if not res.converged:
        who = "the tip" if blades == 1 else f"blade {b}'s tip"
        raise SolverError(f"wear: the vibration with {who} at {target:.4g} m did not solve at "
                          f"{omega / 2 / np.pi:.3f} Hz ({res.reason}); try a smaller wear.tip_amplitude_m")
    return ap, res, b


@dataclass
class Border:
    """The held amplitude's border of a vibration state: ∂R/∂s (n,) [N], ∂rate/∂s (p,)
    [m/cycle], and the constraint row's ∂/∂x (n,) [N/m] and ∂/∂s [N]."""

    R_s: np.ndarray
    rate_s: np.ndarray
    c_x: np.ndarray
    c_s: float

    def bordered(self, col=None) -> tuple:
        """(col, c_x, c_s) of ``[[K, col], [c_xᵀ, c_s]]`` for
        :meth:`workflow.engine.linsolve.StructuredSolve.solve` (``col`` default ∂R/∂s)."""
        return (self.R_s if col is None else col), self.c_x, self.c_s


class BorderedSolve:
    """Newton's linear solve (the protocol of :class:`workflow.engine.solvers.DenseLU`) of the
    held amplitude's bordered Jacobian, matrix-free: ``factor((operator, border))`` takes the
    vibration's operator into ``inner`` (a :class:`~workflow.engine.linsolve.StructuredSolve`),
    ``solve(R)`` is its one GMRES on the bordered system. Tight solves only; no
    Levenberg–Marquardt (the caller turns it off)."""

    name = "bordered-structured"
    inexact = False
    reusable = False

    def __init__(self, inner):
        self.inner = inner
        self.stats = inner.stats
        self.border = None

    def factor(self, J) -> bool:
        op, self.border = J
        return self.inner.factor(op)

    def solve(self, R, eta=None):
        return self.inner.solve(np.asarray(R, dtype=float), eta, border=self.border.bordered())


class _AmplitudeHB:
    """What the wear marches read of a problem's ``hb`` (:mod:`workflow.engine.wear`), for an
    :class:`AmplitudeProblem`: the vibration's own, with the load scale dropped from x."""

    def __init__(self, ap: "AmplitudeProblem"):
        self._ap = ap
        hb = ap.wp.hb
        self.Zr, self.p, self.nh, self.nit, self.method = hb.Zr, hb.p, hb.nh, hb.nit, hb.method
        self.n = ap.n

    @property
    def law(self):
        return self._ap.wp.hb.law

    @property
    def static(self):
        return self._ap.wp.hb.static

    def harmonics(self, x):
        return self._ap.wp.hb.harmonics(np.asarray(x)[:-1])

    @staticmethod
    def load_scale(x) -> float:
        """The dynamic load's scale s at the unknowns ``[x; s]`` (the tip's recovery needs it)."""
        return float(np.asarray(x)[-1])

    def residual_scale(self) -> float:
        return self._ap.sigma

    def operator(self, G):
        return self._ap.wp.hb.operator(G)

    def penalty_apply(self, v):
        return self._ap.wp.hb.penalty_apply(v)


class AmplitudeProblem:
    """Fretting wear with the tip held at the first-harmonic amplitude ``target`` [m] (the
    module docstring): unknowns ``[x; s]``, s the scale of the dynamic load (1: the load the HB
    problem was built with). The residual is ``[R(x; s, W); σ (‖o₁‖/A − 1)]`` (σ the
    vibration's residual scale [N], so one tolerance serves both), its Jacobian bordered by
    ∂R/∂s = −r_F,dyn + G a_F,dyn (the load enters the residual and the DLFT predictor) and the
    constraint's gradient; the wear rate depends on s through the predictor (∂rate/∂s =
    g · a_F,dyn). ``tip``: :func:`tip_map` at the problem's frequency."""

    def __init__(self, wp: WearProblem, tip: tuple, target: float):
        if not (math.isfinite(target) and target > 0):
            raise SceneError(f"wear.tip_amplitude_m = {target!r}: the held tip amplitude must be > 0 m")
        self.wp = wp
        #: J formed (False) or its blocks, bordered matrix-free (True): as the vibration's own
        #: (:attr:`WearProblem.structured`)
        self.structured = wp.structured
        self.C, self.d = (np.asarray(a, dtype=complex) for a in tip)
        self.target = float(target)
        hb = wp.hb
        dyn = fourier.complex_to_real(hb.Fr)     # the unit load's dynamic part: where s enters
        dyn[0] = 0.0
        self._r_dyn, self._a_dyn = hb.load_terms(dyn)
        self._Tc = hb.T if hb.method == "hdhb" else None
        #: the constraint's scale [N]: the unit load's residual scale, fixed (the vibration's own
        #: moves with s)
        self.sigma = hb.residual_scale()
        self.p, self.area, self.k_w, self.share = wp.p, wp.area, wp.k_w, wp.share
        self.averaging, self.eps_path = wp.averaging, wp.eps_path
        self.n = wp.n + 1
        self.hb = _AmplitudeHB(self)
        self.evaluations = 0
        self.tol, self.maxiter = 1e-8, 50       # :meth:`start`'s, kept for :meth:`like`

    # the load scale --------------------------------------------------------
    def set_scale(self, s: float) -> None:
        """The dynamic load × s in the vibration's residual and DLFT predictor."""
        self.wp.hb.scale_load(s)

    def tip(self, x) -> tuple[np.ndarray, float]:
        """(o₁ (n_obs,) complex [m], ‖o₁‖ [m]) at the unknowns ``[x; s]``."""
        x = np.asarray(x, dtype=float)
        o = self.C @ self.wp.hb.harmonics(x[:-1])[1] + x[-1] * self.d
        return o, float(np.linalg.norm(o))

    # W -----------------------------------------------------------------------
    @property
    def W(self) -> np.ndarray:
        return self.wp.W

    def set_wear(self, W) -> None:
        self.wp.set_wear(W)

    # evaluation --------------------------------------------------------------
    def evaluate(self, x, W=None, jacobian: bool = False, dense: bool | None = None) -> WearState:
        """The bordered residual, the wear rate and (optionally) every first derivative at
        ``[x; s]`` and W (always formed)."""
        x = np.asarray(x, dtype=float)
        self.set_scale(x[-1])
        self.evaluations += 1
        dense = not self.structured if dense is None else dense
        st = self.wp.evaluate(x[:-1], W, jacobian=jacobian, dense=dense)
        o, a = self.tip(x)
        sig = self.sigma
        R = np.append(st.R, sig * (a / self.target - 1.0))
        out = WearState(R=R, rate=st.rate, lam=st.lam, slip=st.slip, rate_map=st.rate_map, q2_map=st.q2_map)
        if not jacobian:
            return out
        hb, wp = self.wp.hb, self.wp
        R_s = -self._r_dyn + hb.apply_contact_blocks(st.G, self._a_dyn.reshape(-1, 1))[:, 0]
        a_dyn = self._a_dyn.ravel()[wp._rows]
        rate_s = st.averaged(np.einsum("pa,pa->p", st.g, a_dyn),
                             None if st.g2 is None else np.einsum("pa,pa->p", st.g2, a_dyn))
        w = np.conj(o) @ self.C / max(a, 1e-300)             # ∂‖o₁‖/∂U₁ as Re(w dU₁)
        gc = np.zeros((hb.nc, hb.nr))
        gc[1], gc[2] = w.real, w.imag                        # U₁ = c₁ − i c₂
        gx = (self._Tc.T @ gc if self._Tc is not None else gc).ravel()
        gs = float(np.real(np.conj(o) @ self.d)) / max(a, 1e-300)
        c_x, c_s = (sig / self.target) * gx, (sig / self.target) * gs
        out.G, out.g, out.w, out.G_W, out.g2, out.G_W2 = st.G, st.g, st.w, st.G_W, st.g2, st.G_W2
        if not dense:           # the border of the vibration's blocks (:mod:`workflow.engine.wear.structured`)
            out.border = Border(R_s, rate_s, c_x, c_s)
            return out
        n = wp.n
        out.J = np.empty((n + 1, n + 1))
        out.J[:n, :n], out.J[:n, n], out.J[n, :n], out.J[n, n] = st.J, R_s, c_x, c_s
        out.R_W = np.vstack([st.R_W, np.zeros((1, self.p))])
        out.G_x = np.hstack([st.G_x, rate_s[:, None]])
        return out

    def solve_hb(self, x0, W, *, tol, maxiter=50, dense: bool | None = None) -> tuple:
        """The vibration at W with the tip at its held amplitude, from ``[x0; s0]``: Newton on
        the bordered system; where it fails, the vibration at the fixed scale s0 by the engine's
        whole cascade (:meth:`WearProblem.solve_hb`), then Newton again from there.
        (SolveResult of ``[x; s]``, WearState)."""
        from workflow.engine.solvers import newton

        x0 = np.asarray(x0, dtype=float)
        self.set_wear(W)
        scale = self.sigma
        dense = not self.structured if dense is None else dense
        kw = dict(fun=lambda z: self.evaluate(z).R, tol=tol, scale=scale, maxiter=maxiter)
        if dense:
            def fj(z):
                st = self.evaluate(z, jacobian=True, dense=True)
                return st.R, st.J
        else:
            def fj(z):          # the bordered operator, for :class:`BorderedSolve`
                st = self.evaluate(z, jacobian=True, dense=False)
                return st.R, (self.wp.hb.operator(st.G), st.border)

            kw.update(linear=BorderedSolve(self.wp.linsolver()), lm_fallback=False)
        res = newton(fj, x0, **kw)
        if not res.converged:
            self.set_scale(x0[-1])
            fixed, _ = self.wp.solve_hb(x0[:-1], W, tol=tol, maxiter=maxiter, dense=dense)
            if fixed.converged:
                alt = newton(fj, np.append(fixed.x, x0[-1]), **kw)
                alt.iterations += res.iterations + fixed.iterations
                alt.jacobian_evaluations += res.jacobian_evaluations + fixed.jacobian_evaluations
                if alt.converged or alt.residual_norm < res.residual_norm:
                    res = alt
        return res, self.evaluate(res.x, jacobian=True, dense=dense)

    # what the matrix-free steps read (:mod:`workflow.engine.wear.structured`)
    def linsolver(self):
        return self.wp.linsolver()

    @property
    def _rows(self):
        return self.wp._rows

    def total_rate_jacobian(self, st: WearState) -> np.ndarray:
        return WearProblem.total_rate_jacobian(self, st)

    def like(self, wp: WearProblem, x):
        """(AmplitudeProblem, its ``[x; s]``) of another vibration problem ``wp`` of the same model
        and frequency (a check's: finer Nh, larger ε) holding the same tip amplitude, started
        from its vibration x at the unit load (:meth:`start`, at this problem's tolerance)."""
        other = AmplitudeProblem(wp, (self.C, self.d), self.target)
        res = other.start(x, tol=self.tol, maxiter=self.maxiter)
        return other, res.x

    def start(self, x, *, tol: float, maxiter: int = 50, scale: float = 1.0):
        """``[x; s]`` with the tip at the held amplitude from the vibration x under ``scale`` × the
        unit load: s from the tip's amplitude at x (the response is linear in the load while
        the interface sticks), x scaled alike, then :meth:`solve_hb`; where that fails, by
        continuation in the amplitude from x's own (:meth:`_continued`). Returns its SolveResult."""
        self.tol, self.maxiter = float(tol), int(maxiter)
        x = np.asarray(x, dtype=float)
        _, a = self.tip(np.append(x, scale))
        res, _ = self.solve_hb(self._scaled(np.append(x, scale), self.target / max(a, 1e-300)), self.W,
                               tol=tol, maxiter=maxiter)
        if res.converged or not a > 0:
            return res
        return self._continued(np.append(x, scale), a, spent=res)

    def _scaled(self, z, r: float) -> np.ndarray:
        """``[x; s]`` with the dynamic harmonics of x and the load scale s × r."""
        hb = self.wp.hb
        c = hb.coefficients(z[:-1]).copy()
        c[1:] *= r
        return np.append(hb.unknowns_from_coefficients(c), z[-1] * r)

    def _continued(self, z, a: float, spent=None):
        """From ``[x; s]`` (a solution with the tip at ``a`` [m]) to the held amplitude along
        amplitudes in geometric steps (:data:`CONTINUATION_STEPS` of them, a failed step
        halved at most :data:`CONTINUATION_HALVINGS` times), each from the last solution
        scaled. Far into slip (a tied resonance's load from the stuck guess) Newton's jump
        straight to the target can fail where each step's change of the slip pattern is small.
        Returns the last SolveResult (not converged if a step could not be made); its
        iterations count every attempt, ``spent``'s included."""
        target, la, lt = self.target, math.log(a), math.log(self.target)
        step = (lt - la) / CONTINUATION_STEPS
        its, jac = (0, 0) if spent is None else (spent.iterations, spent.jacobian_evaluations)
        halvings, res = 0, spent
        try:
            while la != lt:
                nxt = lt if abs(lt - la) <= abs(step) * (1 + 1e-12) else la + step
                self.target = math.exp(nxt)
                res, _ = self.solve_hb(self._scaled(z, math.exp(nxt - la)), self.W, tol=self.tol,
                                       maxiter=self.maxiter)
                its, jac = its + res.iterations, jac + res.jacobian_evaluations
                if res.converged:
                    z, la = res.x, nxt
                elif halvings < CONTINUATION_HALVINGS:
                    step, halvings = 0.5 * step, halvings + 1
                else:
                    break
        finally:
            self.target = target
        res.iterations, res.jacobian_evaluations = its, jac
        return res

