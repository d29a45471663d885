"""The EPMC residual and its exact Jacobian at one modal amplitude (scaled rows, dimensionless)."""
from __future__ import annotations

import numpy as np

from workflow.engine import fourier
from workflow.engine.contact import ContactLaw, dlft
from workflow.engine.linsolve import zb_apply
from workflow.engine.studies.nlmodes.structure import _Cond, _condense, _Structure


class _EPMC:
    """Residual and Jacobian of the EPMC at modal amplitude ``a`` (set by :meth:`at`).

    Unknowns v = [X (nc, na) real coefficients, ω, ξ]; residual rows (scaled, dimensionless):
    the HB equations (nc, na) ``Z X − F + [Λ; 0]``, then ``q̂₁ᴴ M q̂₁ / a² − 1`` and the phase
    ``X[1s, η] / a``."""

    def __init__(self, st: _Structure, law: ContactLaw, nh: int, nit: int, anchor, F0, max_passes: int):
        self.st, self.law, self.nh, self.nit = st, law, int(nh), int(nit)
        self.nc = fourier.n_coef(nh)
        self.nr, self.na, self.p = st.nr, st.na, law.p
        self.nx = self.nc * self.na
        self.n = self.nx + 2
        self.E = fourier.time_from_coef_matrix(nh, nit)
        self.Q = fourier.coef_from_time_matrix(nh, nit)
        self.anchor = np.asarray(anchor, float).reshape(self.p, 2)
        self.eps = law.eps().reshape(self.nr)
        self.shift = law.offset().reshape(self.nr)
        self.F = np.zeros((self.nc, self.na))
        self.F[0] = F0
        self.max_passes = int(max_passes)
        self.static_scale = max(float(np.linalg.norm(F0)), 1e-300)
        self._cond = None
        self.a = 1.0
        self.omega_ref = st.omega_tied

    def at(self, a: float):
        """Amplitude a and the row weights of a."""
        self.a = float(a)
        return self.weights(a)

    def weights(self, a: float):
        """Row scaling: the static rows by ‖F_0‖, the dynamic ones by the inertia force of the
        tied mode at amplitude a, ω² a ‖Mφ‖ (the η rows by ω² a)."""
        dyn = self.omega_ref ** 2 * float(a) * self.st.mass_force
        w = np.full((self.nc, self.na), 1.0 / dyn)
        w[0, :] = 1.0 / self.static_scale
        w[:, self.nr] *= self.st.mass_force            # the η rows are modal forces (N/√kg)
        self.w = w.ravel()
        return self

    def cond(self, omega, xi) -> _Cond:
        c = self._cond
        if c is None or c.omega != omega or c.xi != xi:
            c = self._cond = _condense(self.st, omega, xi, self.nh)
        return c

    def split(self, v):
        return v[:self.nx].reshape(self.nc, self.na), float(v[self.nx]), float(v[self.nx + 1])

    def contact(self, X, L, jacobian: bool):
        nr = self.nr
        pred = self.F[:, :nr] - L[:, :nr] + self.eps * X[:, :nr]
        pred[0] += self.eps * self.shift
        lam_u = (self.E @ pred).reshape(self.nit, self.p, 3)
        return dlft(self.law, lam_u, self.anchor, basis=self.E, jacobian=jacobian, max_passes=self.max_passes,
                    tol=1e-10, rows=self.Q if jacobian else None)

    def first_harmonic(self, X, c: _Cond):
        """w₁ = [x_a; −A₁ x_a] (m,) complex: the full first harmonic in w coordinates."""
        xa = X[1] - 1j * X[2]
        return np.concatenate([xa, -c.A[1] @ xa])

    def evaluate(self, v, jacobian: bool = True):
        X, omega, xi = self.split(v)
        c = self.cond(omega, xi)
        nr, nc, na, nx = self.nr, self.nc, self.na, self.nx
        L = zb_apply(c.Z, X)
        res = self.contact(X, L, jacobian)
        Lam = fourier.complex_to_real(fourier.to_freq(res.lam.reshape(self.nit, nr), self.nh))
        R = L - self.F
        R[:, :nr] += Lam
        w1 = self.first_harmonic(X, c)
        Mw = self.st.Mt @ w1
        a2 = self.a ** 2
        g = float(np.real(np.vdot(w1, Mw))) / a2 - 1.0
        ph = X[2, nr] / self.a
        Rs = np.concatenate([R.ravel() * self.w, [g, ph]])
        if not jacobian:
            return Rs, None, res
        J = np.zeros((self.n, self.n))
        Zb = fourier.real_block_diag(c.Z)
        J[:nx, :nx] = Zb
        # contact rows: G (∂a/∂X), ∂a/∂X = ε[I 0] − Zb[contact rows]
        G = np.ascontiguousarray(res.dlam.transpose(1, 0, 2, 3)).reshape(self.p, 3 * nc, 3 * nc)
        Pa = -Zb.reshape(nc, na, nx)[:, :nr, :].copy()
        idx = np.arange(nc)[:, None] * na + np.arange(nr)[None, :]
        Pa.reshape(nc * nr, nx)[np.arange(nc * nr), idx.ravel()] += np.tile(self.eps, nc)
        dw = zb_apply(c.dZw, X)
        dx = zb_apply(c.dZx, X)
        cols = np.concatenate([Pa.reshape(nc, nr, nx), -dw[:, :nr, None], -dx[:, :nr, None]], axis=2)
        J[:nx, nx] = dw.ravel()
        J[:nx, nx + 1] = dx.ravel()
        k = cols.shape[2]
        Vp = cols.reshape(nc, self.p, 3, k).transpose(1, 0, 2, 3).reshape(self.p, 3 * nc, k)
        Gc = np.matmul(G, Vp).reshape(self.p, nc, 3, k).transpose(1, 0, 2, 3).reshape(nc, nr, k)
        Jv = J[:nx].reshape(nc, na, self.n)
        Jv[:, :nr, :] += Gc
        J[:nx] *= self.w[:, None]
        # normalisation: ∂(w₁ᴴ M w₁)/∂X₁c = 2 Re(H x), ∂/∂X₁s = −2 Im(H x), H = Y₁ᴴ M Y₁
        Hx = Mw[:na] - c.A[1].conj().T @ Mw[na:]
        J[nx, na:2 * na] = 2.0 * Hx.real / a2
        J[nx, 2 * na:3 * na] = -2.0 * Hx.imag / a2
        D1, dD1w, dD1x = c.D1
        for col, dD in ((nx, dD1w), (nx + 1, dD1x)):
            if self.st.m > na:
                dwR = -np.linalg.solve(D1[na:, na:], dD[na:] @ w1)
                J[nx, col] = 2.0 * float(np.real(np.vdot(Mw[na:], dwR))) / a2
        J[nx + 1, 2 * na + nr] = 1.0 / self.a
        return Rs, J, res

    # ---------------------------------------------------------------- post-processing
    def harmonics_w(self, X, c: _Cond) -> np.ndarray:
        """Harmonics (Nh+1, m) of the motion in w coordinates (the condensed modes recovered)."""
        Xa = fourier.real_to_complex(X)                      # (Nh+1, na)
        out = np.empty((self.nh + 1, self.st.m), complex)
        out[:, :self.na] = Xa
        if self.st.m > self.na:
            out[0, self.na:] = -(c.A[0].real @ X[0]) + np.linalg.solve(
                self.st.Kt[self.na:, self.na:], self.st.f0t[self.na:])
        out[1:, self.na:] = -np.einsum("jrn,jn->jr", c.A[1:], Xa[1:])
        return out
