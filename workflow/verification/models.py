"""The verification cases as reduced models (``docs/contracts.md`` §4, §6).

One contact pair per friction element, relative DOFs ``u_r = [n, t1, t2]``,
the ground as the disk side, preload through ``f_static`` (−N on the normal
DOF, so that λ_N = −N < 0 in contact). Every model has at least one DOF that
is not a contact DOF: :func:`workflow.engine.condense.condense` needs a non-empty
interior block (a model made only of contact DOFs fails in LAPACK) — for the
1-DOF oscillator it is an unloaded, uncoupled unit oscillator ("witness"),
which changes nothing (massless, so it has no resonance).

* :func:`coulomb` — Den Hartog's oscillator: the mass itself rubs on the
  ground (its t1 DOF is the pair's t1), ``F_f = μN``.
* :func:`jenkins` — a linear structure (M, C, K) with grounded Jenkins pads:
  pad i is a massless contact node tied to structure DOF ``a_i`` by a
  tangential spring k_i; its normal DOF carries the preload N0_i and a
  stiffness row ``cN_i`` coupling it to the structure, so that in contact
  (u_N = 0) the normal load is ``N_i = N0_i + cN_i·x``.
* :func:`two_dof_damper`, :func:`pad_chain` — the concrete structures of
  the suite.

Units SI. Each function returns ``(ReducedModel, Spec)``: the spec holds
the physical data the independent references need.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workflow.engine.model import ReducedModel
from workflow.verification.timeint import Pads

#: normal stiffness of a pad's normal DOF relative to the largest structural
#: stiffness: only felt when a pad separates, large so K stays positive definite
#: with the coupling rows cN.
NORMAL_STIFFNESS = 1e3


@dataclass
class Spec:
    """Physical data of a case (SI): structure M, C, K (n×n), cos(ωt) force f (n,),
    observed structure DOF, friction coefficient μ and the pads (None: the
    Coulomb oscillator, then m, k, c, N, F0 are in ``coulomb``)."""

    name: str
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    f: np.ndarray
    observe: int
    mu: float
    pads: Pads | None = None
    coulomb: dict = field(default_factory=dict)

    @property
    def omega_n(self) -> float:
        """First natural frequency of the structure with the pads tied (rad/s)."""
        K = self.K.copy()
        if self.pads is not None:
            K[self.pads.dof, self.pads.dof] += self.pads.k
        w2 = np.linalg.eigvals(np.linalg.solve(self.M, K)).real
        return float(np.sqrt(np.min(w2[w2 > 0])))


def _model(M, C, K, B, fs, fh, O, p) -> ReducedModel:
    return ReducedModel(M=M, K=K, C=C, B=B, f_static=fs, f_harmonic=fh, O=O, area=np.ones(p), gap=np.zeros(p),
                        flank=np.zeros(p, dtype=int), position=np.zeros((p, 3)))


def coulomb(m: float, k: float, c: float, normal: float, force: float, mu: float,
            name: str = "coulomb") -> tuple[ReducedModel, Spec]:
    """``m ẍ + c ẋ + k x + μN sgn ẋ = F0 cos ωt``: q = [u_n, u_t1, u_t2, witness] (the normal
    and t2 DOFs have the same m, k, c as t1; t2 is unloaded and stays at 0)."""
    M = np.diag([m, m, m, 0.0])     # a massless witness: D_yy = k at every ω, never resonant
    K = np.diag([k, k, k, k])
    C = np.diag([c, c, c, 0.0])
    B = np.eye(3, 4)
    fs = np.array([-normal, 0.0, 0.0, 0.0])
    fh = np.array([0.0, force, 0.0, 0.0])
    O = np.array([[0.0, 1.0, 0.0, 0.0]])
    spec = Spec(name=name, M=np.array([[m]]), C=np.array([[c]]), K=np.array([[k]]), f=np.array([force]),
                observe=0, mu=mu, coulomb=dict(m=m, k=k, c=c, friction=mu * normal, force=force))
    return _model(M, C, K, B, fs, fh, O, 1), spec


def jenkins(M, C, K, f, observe: int, pads: Pads, name: str) -> tuple[ReducedModel, Spec]:
    """Structure (n DOFs) + p massless pads (3 DOFs each, appended): q = [x, pad0 n t1 t2, …]."""
    M, C, K, f = (np.asarray(a, float) for a in (M, C, K, f))
    n, p = K.shape[0], len(pads.dof)
    size = n + 3 * p
    Mq, Cq, Kq = np.zeros((size, size)), np.zeros((size, size)), np.zeros((size, size))
    Mq[:n, :n], Cq[:n, :n], Kq[:n, :n] = M, C, K
    kn = NORMAL_STIFFNESS * max(np.abs(K).max(), pads.k.max())
    B = np.zeros((3 * p, size))
    fs = np.zeros(size)
    for i in range(p):
        dn, dt, d2 = n + 3 * i, n + 3 * i + 1, n + 3 * i + 2
        a = int(pads.dof[i])
        ki = float(pads.k[i])
        Kq[np.ix_([a, dt], [a, dt])] += ki * np.array([[1.0, -1.0], [-1.0, 1.0]])
        Kq[d2, d2] += ki
        Kq[dn, dn] += kn
        Kq[dn, :n] += pads.cN[i]
        Kq[:n, dn] += pads.cN[i]
        B[3 * i:3 * i + 3, [dn, dt, d2]] = np.eye(3)
        fs[dn] = -float(pads.N0[i])
    fh = np.zeros(size)
    fh[:n] = f
    O = np.zeros((1, size))
    O[0, observe] = 1.0
    spec = Spec(name=name, M=M, C=C, K=K, f=f, observe=observe, mu=float(pads.mu), pads=pads)
    return _model(Mq, Cq, Kq, B, fs, fh, O, p), spec


def two_dof_damper(*, mu: float = 0.5, N0: float = 0.3, coupling: float = 0.1, force: float = 0.1,
                   zeta: float = 0.01) -> tuple[ReducedModel, Spec]:
    """ground —k1— m1 —k2— m2, force on m2, a Jenkins pad (k_d = 1 N/m) on m1 whose normal
    load varies with the motion, ``N = N0 + coupling·x1`` (N). Stiffness-proportional
    damping C = (2ζ/ω_ref) K with ω_ref = 1 rad/s. Observed: m2."""
    M = np.diag([1.0, 0.2])
    K = np.array([[1.5, -0.5], [-0.5, 0.5]])
    pads = Pads(dof=np.array([0]), k=np.array([1.0]), mu=mu, N0=np.array([N0]), cN=np.array([[coupling, 0.0]]))
    return jenkins(M, 2 * zeta * K, K, [0.0, force], 1, pads, "2dof-damper")


def pad_chain(*, n: int = 10, pads: int = 8, mu: float = 0.5, force: float = 1.0,
              zeta: float = 0.01) -> tuple[ReducedModel, Spec]:
    """A lumped cantilever: n unit masses in a chain (k = 100 N/m between them and to the
    ground at the root), the harmonic force at the tip, Jenkins pads on the first
    ``pads`` masses (the root), stiffness k_d = 50…120 N/m and preload N0 = 0.5…2 N
    graded along the root so they slip one after another (a slip band).
    Stiffness-proportional damping, ζ at the first tied mode. Observed: the tip."""
    k = 100.0
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k
        if i + 1 < n:
            K[np.ix_([i, i + 1], [i, i + 1])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    M = np.eye(n)
    f = np.zeros(n)
    f[-1] = force
    kd = np.linspace(120.0, 50.0, pads)
    N0 = np.linspace(2.0, 0.5, pads)
    P = Pads(dof=np.arange(pads), k=kd, mu=mu, N0=N0, cN=np.zeros((pads, n)))
    Kt = K.copy()
    Kt[P.dof, P.dof] += kd
    w1 = float(np.sqrt(np.min(np.linalg.eigvalsh(Kt))))
    return jenkins(M, 2 * zeta / w1 * K, K, f, n - 1, P, "pad-chain")


def linear_limit(spec: Spec, omega: float, tied: bool) -> float:
    """First-harmonic amplitude (m) at the observed DOF in a linear limit, from the
    structure's own matrices: tied (μ → ∞: the pads' springs grounded, or the
    Coulomb mass held, x = 0) or free (μ = 0: the pads exert nothing)."""
    if spec.pads is None and tied:
        return 0.0
    K = spec.K.astype(complex)
    if tied:
        K[spec.pads.dof, spec.pads.dof] += spec.pads.k
    D = K - omega ** 2 * spec.M + 1j * omega * spec.C
    return float(abs(np.linalg.solve(D, spec.f.astype(complex))[spec.observe]))


def light_pad_chain(*, n: int = 10, pads: int = 8, mu: float = 0.3, force: float = 1.0, zeta: float = 0.01,
                    pad_mass: float = 1e-3, coupling: float = 0.2, contact_ratio: float = 1e3
                    ) -> tuple[ReducedModel, Spec]:
    """Issue 47's chain: the cantilever of :func:`pad_chain` whose 8 root masses each hold a
    *light pad* (mass ``pad_mass``, kg) on a spring k_d = 120…50 N/m; the pad rests on
    rigid ground and rubs on it (μ), normal load ``N_i = N0_i + coupling·x_{a_i}``
    (N0 = 2…0.5 N) varying with the motion of the mass that carries it.

    * The reduced model (HB): q = [x (n), pad0 n t1 t2, …]; the contact DOF *is* the pad's
      tangential DOF (mass ``pad_mass``, t2 likewise, unloaded), the ground rigid — DLFT's
      ε is then the only contact compliance.
    * The spec (time integration): the pads are structure DOFs n…n+p−1 (mass ``pad_mass``)
      carrying grounded Jenkins elements of stiffness ``contact_ratio`` × k_d: the
      near-rigid contact of the reference.

    Damping: C = (2ζ/ω₁)·K_s, K_s the chain plus the pad springs (the same in both),
    ω₁ the first mode with the pads stuck. Observed: the tip."""
    k = 100.0
    Kc = np.zeros((n, n))
    for i in range(n):
        Kc[i, i] += k
        if i + 1 < n:
            Kc[np.ix_([i, i + 1], [i, i + 1])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    kd = np.linspace(120.0, 50.0, pads)
    N0 = np.linspace(2.0, 0.5, pads)
    # structure of the time integration: chain + pads (DOFs n + i), pad i on mass i
    m = n + pads
    Ks = np.zeros((m, m))
    Ks[:n, :n] = Kc
    for i in range(pads):
        Ks[np.ix_([i, n + i], [i, n + i])] += kd[i] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    Ms = np.diag(np.concatenate([np.ones(n), np.full(pads, pad_mass)]))
    Kt = Kc.copy()
    Kt[np.arange(pads), np.arange(pads)] += kd       # pads stuck on rigid ground
    w1 = float(np.sqrt(np.min(np.linalg.eigvalsh(Kt))))
    Cs = 2 * zeta / w1 * Ks
    f = np.zeros(m)
    f[n - 1] = force
    cN = np.zeros((pads, m))
    cN[np.arange(pads), np.arange(pads)] = coupling
    P = Pads(dof=n + np.arange(pads), k=contact_ratio * kd, mu=mu, N0=N0, cN=cN)
    spec = Spec(name="light-pad-chain", M=Ms, C=Cs, K=Ks, f=f, observe=n - 1, mu=float(mu), pads=P)
    # the reduced model: pad DOFs become the contact pairs' t1 (t2 a copy, unloaded)
    size = n + 3 * pads
    Mq, Cq, Kq = np.zeros((size, size)), np.zeros((size, size)), np.zeros((size, size))
    Mq[:n, :n] = np.eye(n)
    Kq[:n, :n] = Kc
    kn = NORMAL_STIFFNESS * max(np.abs(Kc).max(), kd.max())
    B = np.zeros((3 * pads, size))
    fs = np.zeros(size)
    for i in range(pads):
        dn, dt, d2 = n + 3 * i, n + 3 * i + 1, n + 3 * i + 2
        kk = kd[i] * np.array([[1.0, -1.0], [-1.0, 1.0]])
        Kq[np.ix_([i, dt], [i, dt])] += kk
        Kq[d2, d2] += kd[i]                     # t2: grounded like the pad, never loaded
        Mq[dt, dt] = Mq[d2, d2] = pad_mass
        Kq[dn, dn] += kn
        Kq[dn, i] += coupling
        Kq[i, dn] += coupling
        B[3 * i:3 * i + 3, [dn, dt, d2]] = np.eye(3)
        fs[dn] = -float(N0[i])
    Cq = 2 * zeta / w1 * np.where(np.abs(Kq) > 0, Kq, 0.0)
    # damping only on the structure and the pad springs (not the normal stiffness, not the coupling)
    Cq[:, [n + 3 * i for i in range(pads)]] = 0.0
    Cq[[n + 3 * i for i in range(pads)], :] = 0.0
    fh = np.zeros(size)
    fh[n - 1] = force
    O = np.zeros((1, size))
    O[0, n - 1] = 1.0
    return _model(Mq, Cq, Kq, B, fs, fh, O, pads), spec
