"""Archard fretting wear references (issue 48 item 4 a, b, d), independent of the HB/DLFT code.

Units SI (N, m, N/m, m², cycles). The wear law is the engine's (eq. 21,
:func:`workflow.engine.wear.wear_per_cycle`): per cycle the depth of pair i grows by

    ΔW_i = k_w ∮ p_i |du_T,i| = k_w (N_i / A_i) s_i,      p_i = N_i / A_i,

k_w [m²/N], N_i the normal load [N] (constant over the cycle in every case
below: nothing excites the normal direction), A_i the pair's area [m²], s_i
the slip path of the slider per cycle [m]. The depth W_i opens the normal gap
(``g = u_N + gap + W``): a contact whose normal load comes through a spring
k_n loses ``k_n·ΔW`` of it. "Cycles" n is the cycle count, a continuous
variable (wear per cycle is tiny: dW/dn = ΔW).

The slip of a Jenkins element (tangential spring k_t in series with a
Coulomb slider of limit μN, N constant) whose far end moves with one maximum
and one minimum per cycle, peak to peak 2X: the slider moves only while the
spring force is at the limit, from one turning point to the next, by
``2X − 2μN/k_t`` each way, so

    s(N) = 4 (X − μN/k_t)   for μN < k_t X,      0 otherwise (it sticks).      (J)

(a) ``JenkinsWear`` — one Jenkins element, far end imposed ``X cos ωt``, normal
    load through a preloaded normal spring: N(W) = N₀ − k_n W = k_n (δ₀ − W),
    δ₀ = N₀/k_n. Then dN/dn = −k_n dW/dn = −k_n k_w (N/A)·4(X − μN/k_t), i.e.

        dN/dn = −r N (1 − N/N_c),   r = 4 k_n k_w X / A,   N_c = k_t X / μ,

    a logistic equation run backwards. For 0 < N₀ < N_c (slip from the start):

        N(n) = N_c / (1 + (N_c/N₀ − 1) e^{r n}),     W(n) = (N₀ − N(n)) / k_n,
        n(N) = ln[ N₀ (N_c − N) / (N (N_c − N₀)) ] / r.

    Cases: N₀ ≥ N_c — the element sticks (s = 0) and nothing ever wears (W ≡ 0;
    wear would only *lower* N, so a slipping element never comes back to
    stick: the "wear stops at μN = k_t X" of the issue does not happen here);
    0 < N₀ < N_c — N → 0 and W → δ₀: the worn steady state is the contact
    unloaded to zero load at zero gap, reached only asymptotically (N ∝ e^{−rn}:
    lift-off never happens in finite n). The wear rate r_W = k_w N·4(X − μN/k_t)/A
    is largest at N = N_c/2 = k_t X/(2μ), reached at n* = ln(N₀/(N_c − N₀))/r
    when N₀ > N_c/2 (else the rate is largest at n = 0 and only decays).

(b) ``PunchWear`` — a rigid punch pressed by a dead load N₀ onto m contacts;
    contact i: normal spring k_n,i between punch and contact node, tangential
    Jenkins element (k_t,i, μ), area A_i, initial gap g_i ≥ 0; the punch slides
    with an imposed amplitude X (gross slip: μN_i < k_t,i X everywhere). With d
    the punch's approach, N_i = k_n,i (d − g_i − W_i)₊ and Σ N_i = N₀ (the
    static share, :meth:`PunchWear.loads`, exact by sorting). The rates
    φ_i(N) = a_i N (X − b_i N), a_i = 4k_w/A_i, b_i = μ/k_t,i.

    *There is no worn steady state* (no W with all rates 0) under a dead load in
    gross slip: the load N₀ never goes away, so some contact always carries
    it and slips. What is reached instead is the *steady wear-rate state*: every
    contact loaded (d grows without bound, so every gap closes), the loads
    constant and every contact wearing at the punch's sinking speed V:

        φ_i(N_i∞) = V,  Σ N_i∞ = N₀  ⇒  N_i∞(V) = [X − √(X² − 4 b_i V/a_i)] / (2 b_i)

    (the root with N < N_c,i/2, the stable one; V by a scalar root of Σ N_i∞ = N₀;
    b → 0: the pressures equalise, p_i = N₀/ΣA). Stable iff every N_i∞ < N_c,i/2;
    W_i(n) → V n + c_i with the *profile* fixed in closed form:

        W_i − W_j → (g_j − g_i) + N_j∞/k_n,j − N_i∞/k_n,i,

    the initial gap profile, offset by the contact compliances. (Above N_c/2
    the equal-rate state is unstable, the load gathers on fewer contacts until
    they stick: a path-dependent state not covered here.)

    The whole path in closed form for three contacts, a centre (index 1) and two
    equal edges (0, 2) with gap g_e, by symmetry one unknown s = N_centre,
    N_edge = (N₀ − s)/2 (:meth:`PunchWear.symmetric3`). Phase 1 (edges open, if
    g_e − g_c > N₀/k_c): the centre alone carries N₀ and wears at φ_c(N₀),
    W_c = φ_c(N₀) n, until d = g_c + W_c + N₀/k_c reaches g_e at
    n₁ = (g_e − g_c − N₀/k_c)/φ_c(N₀). Phase 2: from s/k_c = d − g_c − W_c and
    N_e/k_e = d − g_e − W_e,

        ds/dn = κ [φ_e((N₀ − s)/2) − φ_c(s)] = κ Q(s),   κ = 1/(1/k_c + 1/(2k_e)),

    Q(s) = q₂s² + q₁s + q₀ with q₂ = a_c b_c − a_e b_e/4,
    q₁ = a_e (b_e N₀ − X)/2 − a_c X, q₀ = a_e N₀ (X − b_e N₀/2)/2: a Riccati
    equation with constant coefficients. With roots r₁ (stable, κQ'(r₁) < 0) and r₂,
    E(n) = K e^{λ(n − n₁)}, λ = κ q₂ (r₁ − r₂), K = (s₁ − r₁)/(s₁ − r₂):

        s(n) = r₁ + (r₁ − r₂) E/(1 − E),

    and the centre's depth W_c(n) = W_c(n₁) + ∫ φ_c(s) dn = W_c(n₁) + ∫ φ_c(s) ds/(κQ(s)),
    by partial fractions (φ_c(s) = −a_c b_c (s − r₁)(s − r₂) + R(s) with R linear and
    R(r) = φ_c(r) at both roots, so R(s)/((s − r₁)(s − r₂)) = P₁/(s − r₁) + P₂/(s − r₂),
    P₁ = φ_c(r₁)/(r₁ − r₂), P₂ = φ_c(r₂)/(r₂ − r₁); the P₁ term grows as φ_c(r₁)(n − n₁) = V(n − n₁)):

        ∫ φ_c dn = −(a_c b_c/κq₂)(s − s₁) + (P₁/κq₂)[λ(n − n₁) + ln((1 − K)/(1 − E))]
                   + (P₂/κq₂) ln((1 − K)/(1 − E));

    then d = g_c + W_c + s/k_c and W_e = d − g_e − N_e/k_e. (q₂ = 0: Q is linear,
    s − r₁ decays as e^{κq₁(n − n₁)}, same steps.) Any m: :meth:`PunchWear.integrate`
    (solve_ivp, restarted where a gap closes).

(d) ``OscillatorWear`` — a damped 1-DOF oscillator (m, c, k, force F cos ωt) with
    a grounded Jenkins pad (k_t, μ) whose normal load is N = N₀ − k_n W. Per N the
    periodic response is the event-driven stick–slip steady state of
    :mod:`workflow.verification.timeint` (no regularisation, no HB); the slip per
    cycle is (J) with 2X the mass's peak-to-peak motion (the pad slides from one
    turning point of the mass to the next; checked: one maximum and one minimum
    per period), the extremes located on a dense re-sampling and a parabola.
    The wear is then marched in the cycle variable with cycle jumps
    (:meth:`OscillatorWear.march`: Heun's RK2 in n, step control on W, each stage
    one steady state at the stage's N). The worn steady state is again N → 0,
    W → δ₀ = N₀/k_n (s(N) > 0 for every N > 0: a lighter pad slips more), with the
    closed-form final decay ``N ∝ e^{−r₀ n}``, r₀ = k_n k_w s(0)/A,
    s(0) = 4|X_free|, X_free = F / |k − mω² + icω| (the oscillator without the pad).

Each case also writes itself as a lumped :class:`~workflow.engine.model.ReducedModel`
(``*.model()``) for the engine. The imposed displacement ``X cos ωt`` at a
Jenkins spring's far end is written as a force ``k_t X cos ωt`` on the massless
contact node with the spring k_t grounded: the node feels ``k_t (X cos ωt − u)``
either way — the same equation, not an approximation (a stiff drive spring K_d
with force K_d X would leave a relative error k_t/K_d in the drive).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = ["JenkinsWear", "PunchWear", "OscillatorWear", "jenkins_slip", "archard_rate"]


def jenkins_slip(N, X, mu, k_t):
    """Slip path per cycle (m) of a Jenkins element (J): ``4(X − μN/k_t)₊``."""
    return 4.0 * np.maximum(np.asarray(X, float) - mu * np.asarray(N, float) / np.asarray(k_t, float), 0.0)


def archard_rate(N, A, k_w, slip):
    """Wear depth per cycle (m/cycle), ``k_w (N/A) s`` for N > 0, else 0."""
    return k_w * np.maximum(np.asarray(N, float), 0.0) / np.asarray(A, float) * np.asarray(slip, float)


def _model(M, K, B, fs, fh, O, area, gap, C=None):
    from workflow.engine.model import ReducedModel

    p = len(area)
    return ReducedModel(M=M, K=K, C=np.zeros_like(K) if C is None else C, B=B, f_static=fs, f_harmonic=fh, O=O,
                        area=np.asarray(area, float), gap=np.asarray(gap, float), flank=np.zeros(p, dtype=int),
                        position=np.zeros((p, 3)))


# ------------------------------------------------------------------ (a) one Jenkins element
@dataclass(frozen=True)
class JenkinsWear:
    """(a): Jenkins element (k_t, μ), far end imposed X cos ωt, normal load N₀ − k_n W."""

    k_t: float
    k_n: float
    mu: float
    X: float
    N0: float
    A: float
    k_w: float

    @property
    def Nc(self) -> float:
        """Load at which the element sticks, k_t X/μ (N)."""
        return self.k_t * self.X / self.mu

    @property
    def delta0(self) -> float:
        """Depth that unloads the contact, N₀/k_n (m)."""
        return self.N0 / self.k_n

    @property
    def r(self) -> float:
        """Logistic rate constant 4 k_n k_w X / A (1/cycle)."""
        return 4.0 * self.k_n * self.k_w * self.X / self.A

    @property
    def regime(self) -> str:
        if self.N0 <= 0.0:
            return "open"
        return "stick" if self.N0 >= self.Nc else "slip"

    def rate_of_load(self, N):
        """dW/dn (m/cycle) at normal load N."""
        return archard_rate(N, self.A, self.k_w, jenkins_slip(N, self.X, self.mu, self.k_t))

    def rate_of_wear(self, W):
        """dW/dn (m/cycle) at depth W (N = N₀ − k_n W)."""
        return self.rate_of_load(self.N0 - self.k_n * np.asarray(W, float))

    def load(self, n):
        """N(n) (N), closed form."""
        n = np.asarray(n, float)
        if self.regime != "slip":
            return np.full(n.shape, max(self.N0, 0.0))
        # N_c / (1 + (N_c/N₀ − 1) e^{rn}), written to stay finite for large rn
        c = self.Nc / self.N0 - 1.0
        x = self.r * n + math.log(c)
        return np.where(x > 0, self.Nc * np.exp(-x) / (1.0 + np.exp(-np.abs(x))), self.Nc / (1.0 + np.exp(x)))

    def wear(self, n):
        """W(n) (m), closed form: (N₀ − N(n))/k_n."""
        if self.regime != "slip":
            return np.zeros(np.shape(n))
        # (N₀ − N)/k_n = N₀ (1 − e^{−rn}) ... written without cancellation:
        # N₀ − N = N₀ (Nc − N₀)(e^{rn} − 1) / (N₀ + (Nc − N₀) e^{rn})
        n = np.asarray(n, float)
        N0, Nc, r = self.N0, self.Nc, self.r
        em1 = np.expm1(-r * n)                          # e^{−rn} − 1 ∈ (−1, 0]
        e = np.exp(-r * n)
        return N0 * (Nc - N0) * (-em1) / (N0 * e + (Nc - N0)) / self.k_n

    def cycles_to_load(self, N):
        """n at which the load has dropped to N (0 < N ≤ N₀), closed form."""
        N = np.asarray(N, float)
        return np.log(self.N0 * (self.Nc - N) / (N * (self.Nc - self.N0))) / self.r

    def final(self) -> dict:
        """The worn steady state: {N, W, regime} (N [N], W [m])."""
        reg = self.regime
        if reg == "slip":
            return {"N": 0.0, "W": self.delta0, "regime": "unloaded to zero load (asymptotically, N ∝ e^{-rn})"}
        return {"N": max(self.N0, 0.0), "W": 0.0, "regime": "stuck: never wears" if reg == "stick" else "open"}

    def peak(self) -> dict:
        """Largest wear rate: {N (N), n (cycles), rate (m/cycle)}; at N_c/2 if N₀ > N_c/2, else at n = 0."""
        if self.regime != "slip":
            return {"N": max(self.N0, 0.0), "n": 0.0, "rate": 0.0}
        Np = 0.5 * self.Nc if self.N0 > 0.5 * self.Nc else self.N0
        n = math.log(self.N0 / (self.Nc - self.N0)) / self.r if self.N0 > 0.5 * self.Nc else 0.0
        return {"N": Np, "n": n, "rate": float(self.rate_of_load(Np))}

    def integrate(self, n_eval, rtol=1e-12):
        """W(n) by solve_ivp (DOP853) of dW/dn = k_w (N₀ − k_n W)/A · 4(X − μ(N₀ − k_n W)/k_t)₊
        — the same ODE, integrated numerically (the closed form's check)."""
        n_eval = np.asarray(n_eval, float)
        sol = solve_ivp(lambda n, W: self.rate_of_wear(W), (0.0, float(n_eval.max())), [0.0], method="DOP853",
                        t_eval=n_eval, rtol=rtol, atol=1e-6 * rtol * max(self.delta0, 1e-300))
        return sol.y[0]

    def model(self, witness_hz: float = 100.0):
        """ReducedModel, q = [u_n, u_t1, u_t2, witness]: a massless contact node (disk rigid),
        normal spring k_n with the static load −N₀ (λ_N = −N₀ + k_n W in contact), tangential
        springs k_t (t1 loaded by k_t X cos ωt: the imposed far end, exactly), and an uncoupled,
        unloaded witness oscillator (1 kg at ``witness_hz``) that gives the tied frequency the
        condensation and the wear study need; it stays at 0."""
        kw = (2 * np.pi * witness_hz) ** 2
        K = np.diag([self.k_n, self.k_t, self.k_t, kw])
        M = np.diag([0.0, 0.0, 0.0, 1.0])
        fs = np.array([-self.N0, 0.0, 0.0, 0.0])
        fh = np.array([0.0, self.k_t * self.X, 0.0, 0.0])
        return _model(M, K, np.eye(3, 4), fs, fh, np.array([[0.0, 1.0, 0.0, 0.0]]), [self.A], [0.0])


# ------------------------------------------------------------------ (b) rigid punch
@dataclass(frozen=True)
class PunchWear:
    """(b): rigid punch, dead load N₀, m contacts (k_n, k_t, A, gap per contact; μ, X, k_w shared)."""

    k_n: tuple
    k_t: tuple
    A: tuple
    gap: tuple
    mu: float
    X: float
    N0: float
    k_w: float

    def _arr(self, name):
        return np.asarray(getattr(self, name), float)

    @property
    def m(self) -> int:
        return len(self.A)

    @property
    def a(self):
        return 4.0 * self.k_w / self._arr("A")

    @property
    def b(self):
        return self.mu / self._arr("k_t")

    @property
    def Nc(self):
        return self._arr("k_t") * self.X / self.mu

    def loads(self, W) -> tuple[np.ndarray, float]:
        """(N (m,), d): the static share of N₀ at depths W — Σ k_n,i (d − g_i − W_i)₊ = N₀,
        exact (piecewise linear in d, the active set by sorting the thresholds g_i + W_i)."""
        kn, h = self._arr("k_n"), self._arr("gap") + np.asarray(W, float)
        order = np.argsort(h, kind="stable")
        ks, hs = kn[order], h[order]
        for j in range(1, self.m + 1):
            d = (self.N0 + ks[:j] @ hs[:j]) / ks[:j].sum()
            if j == self.m or d <= hs[j]:
                break
        return kn * np.maximum(d - h, 0.0), float(d)

    def rates(self, W) -> np.ndarray:
        """dW/dn (m,) (m/cycle) at depths W."""
        N, _ = self.loads(W)
        return self.a * N * np.maximum(self.X - self.b * N, 0.0)

    def integrate(self, n_eval, rtol=1e-12) -> np.ndarray:
        """W(n) (len(n_eval), m) by solve_ivp (DOP853) of dW/dn = rates(W), restarted at each
        closure of a gap (where the right side has a kink)."""
        n_eval = np.sort(np.asarray(n_eval, float))
        out = np.zeros((n_eval.size, self.m))
        scale = max(float(np.max(self._arr("gap"))), self.N0 / float(np.min(self._arr("k_n"))))
        n0, W = 0.0, np.zeros(self.m)
        closed = self.loads(W)[0] > 0.0         # contacts that touched (an event fires once per contact)
        while True:
            events, which = [], []
            for i in np.flatnonzero(~closed):
                which.append(i)
                ev = (lambda n, w, i=i: self.loads(w)[1] - self.gap[i] - w[i])
                ev.terminal, ev.direction = True, 1
                events.append(ev)
            sel = n_eval >= n0
            sol = solve_ivp(lambda n, w: self.rates(w), (n0, float(n_eval.max())), W, method="DOP853",
                            t_eval=n_eval[sel], events=events or None, rtol=rtol, atol=1e-6 * rtol * scale,
                            dense_output=True)
            hit = [(e[0], which[j]) for j, e in enumerate(sol.t_events or []) if e.size]
            n_end = min((h[0] for h in hit), default=np.inf)
            take = sel & (n_eval <= n_end)
            if take.any():
                out[take] = sol.sol(n_eval[take]).T
            if not hit:
                return out
            closed[[i for t, i in hit if t <= n_end]] = True
            n0, W = n_end, sol.sol(n_end)

    def asymptote(self) -> dict:
        """The steady wear-rate state: {V (m/cycle), N (m,) N, offsets (m,) m: W_i − W_0 as n → ∞,
        stable (bool)}; ValueError where no stable gross-slip state exists (N₀ ≥ Σ N_c,i/2)."""
        a, b, X = self.a, self.b, self.X
        vmax = a * X * X / (4.0 * b)                   # φ_i's maximum, at N_c,i/2

        def loads(V):
            return (X - np.sqrt(np.maximum(X * X - 4.0 * b * V / a, 0.0))) / (2.0 * b)

        if self.N0 >= loads(float(vmax.min())).sum() * (1 - 1e-15):
            raise ValueError("punch: no stable gross-slip wear-rate state (N₀ too large for N_c/2 per contact)")
        V = brentq(lambda v: loads(v).sum() - self.N0, 0.0, float(vmax.min()), xtol=1e-300, rtol=1e-15)
        N = loads(V)
        c = -self._arr("gap") - N / self._arr("k_n")        # W_i = d − g_i − N_i/k_n,i
        return {"V": float(V), "N": N, "offsets": c - c[0], "stable": bool(np.all(N < 0.5 * self.Nc))}

    # closed form, 3 contacts [edge, centre, edge] -------------------------------------------------
    def _check3(self):
        kn, A, g, kt = (self._arr(k) for k in ("k_n", "A", "gap", "k_t"))
        if self.m != 3 or not (kn[0] == kn[2] and A[0] == A[2] and g[0] == g[2] and kt[0] == kt[2]):
            raise ValueError("symmetric3: three contacts, the two edges (0, 2) alike")
        if g[1] > g[0]:
            raise ValueError("symmetric3: the centre must not have the larger gap")
        if np.any(self.N0 >= self.Nc):
            raise ValueError("symmetric3: gross slip needs N₀ < N_c at every contact")

    def symmetric3(self, n) -> np.ndarray:
        """W(n) (len(n), 3), the closed form of the module docstring (edges 0, 2; centre 1)."""
        self._check3()
        n = np.atleast_1d(np.asarray(n, float))
        kn, g = self._arr("k_n"), self._arr("gap")
        a, b, X, N0 = self.a, self.b, self.X, self.N0
        kc, ke, gc, ge = kn[1], kn[0], g[1], g[0]
        ac, bc, ae, be = a[1], b[1], a[0], b[0]
        phic = lambda s: ac * s * (X - bc * s)  # noqa: E731
        out = np.zeros((n.size, 3))
        # phase 1: the centre alone
        n1 = max((ge - gc - N0 / kc) / phic(N0), 0.0)
        p1 = n < n1
        out[p1, 1] = phic(N0) * n[p1]
        Wc1 = phic(N0) * n1
        s1 = N0 if n1 > 0 else float(self.loads(np.zeros(3))[0][1])
        m2 = ~p1
        t = n[m2] - n1
        kap = 1.0 / (1.0 / kc + 0.5 / ke)
        q2 = ac * bc - ae * be / 4.0
        q1 = ae * (be * N0 - X) / 2.0 - ac * X
        q0 = ae * N0 * (X - be * N0 / 2.0) / 2.0
        if abs(q2) <= 1e-14 * abs(q1) * max(N0, 1e-300):
            r1 = -q0 / q1
            lam = kap * q1                                   # s − r1 ∝ e^{λt}, λ < 0
            s = r1 + (s1 - r1) * np.exp(lam * t)
            # φ_c(s) = φ_c(r1) + φ_c'(r1)(s − r1) − a_c b_c (s − r1)²
            e1 = np.expm1(lam * t) / lam
            e2 = np.expm1(2 * lam * t) / (2 * lam)
            u = s1 - r1
            Ic = phic(r1) * t + ac * (X - 2 * bc * r1) * u * e1 - ac * bc * u * u * e2
        else:
            disc = q1 * q1 - 4 * q2 * q0
            ra, rb = (-q1 + math.sqrt(disc)) / (2 * q2), (-q1 - math.sqrt(disc)) / (2 * q2)
            # the stable root: κ Q'(r) = κ q2 (2r + q1/q2) < 0
            r1, r2 = (ra, rb) if kap * (2 * q2 * ra + q1) < 0 else (rb, ra)
            lam = kap * q2 * (r1 - r2)
            K = (s1 - r1) / (s1 - r2)
            E = K * np.exp(lam * t)
            s = r1 + (r1 - r2) * E / (1.0 - E)
            # φ_c(s) = −a_c b_c (s − r1)(s − r2) + R(s), R linear with R(r) = φ_c(r) at the roots
            P1, P2 = phic(r1) / (r1 - r2), phic(r2) / (r2 - r1)
            L = np.log((1.0 - K) / (1.0 - E))
            Ic = (-ac * bc * (s - s1) + P1 * (lam * t + L) + P2 * L) / (kap * q2)
        Wc = Wc1 + Ic
        d = gc + Wc + s / kc
        We = d - ge - 0.5 * (N0 - s) / ke
        out[m2, 1] = Wc
        out[m2, 0] = out[m2, 2] = We
        return out

    def closing_cycles(self) -> float:
        """n₁, the cycle at which the edges touch (symmetric3; 0 if they carry load from the start)."""
        self._check3()
        kn, g = self._arr("k_n"), self._arr("gap")
        phic = self.a[1] * self.N0 * (self.X - self.b[1] * self.N0)
        return max((g[0] - g[1] - self.N0 / kn[1]) / phic, 0.0)

    def model(self, punch_mass: float = 1.0):
        """ReducedModel, q = [v (punch normal), node i: n, t1, t2, …]: the punch (mass
        ``punch_mass``, static load −N₀) on normal springs k_n,i to massless contact nodes;
        each node's t1 grounded through k_t,i and loaded by k_t,i X cos ωt (the punch's imposed
        slide, exactly), t2 through k_t,i, unloaded; gaps g_i. Observed: node 0's t1."""
        m = self.m
        size = 1 + 3 * m
        K, M = np.zeros((size, size)), np.zeros((size, size))
        M[0, 0] = punch_mass
        B = np.zeros((3 * m, size))
        fs, fh = np.zeros(size), np.zeros(size)
        fs[0] = -self.N0
        for i in range(m):
            dn, dt, d2 = 1 + 3 * i, 2 + 3 * i, 3 + 3 * i
            k = float(self.k_n[i])
            K[np.ix_([0, dn], [0, dn])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
            K[dt, dt] += float(self.k_t[i])
            K[d2, d2] += float(self.k_t[i])
            fh[dt] = float(self.k_t[i]) * self.X
            B[3 * i:3 * i + 3, [dn, dt, d2]] = np.eye(3)
        O = np.zeros((1, size))
        O[0, 2] = 1.0
        return _model(M, K, B, fs, fh, O, self._arr("A"), self._arr("gap"))


def layered_punch(A, gap, *, kn: float, kt: float, Ks: float, N0: float, X: float, mu: float, k_w: float):
    """(b) through the contact's interface layer (:mod:`reduction.layer`): ``(PunchWear, model)``.

    The model is a rigid punch (1 kg, dead load −N₀) touching its contacts i directly, each
    contact's structure side driven along t1 by X cos ωt through a spring Ks [N/m] (grounded
    Ks, loaded Ks·X; t2 grounded Ks), with the layer k_n, k_t [N/m³] in series. Its normal springs
    are k_n A_i and the slider sees Ks and k_t A_i in series: the :class:`PunchWear` with those
    k_n,i and k_t,i; the contacts are massless. Observed: contact 0's t1."""
    from reduction.layer import with_interface_layer

    A, gap = np.asarray(A, float), np.asarray(gap, float)
    m = A.size
    size = 1 + 2 * m                                    # the punch's v, then t1, t2 of each contact
    K, M = np.zeros((size, size)), np.zeros((size, size))
    M[0, 0] = 1.0
    B = np.zeros((3 * m, size))
    fs, fh = np.zeros(size), np.zeros(size)
    fs[0] = -N0
    for i in range(m):
        t1, t2 = 1 + 2 * i, 2 + 2 * i
        K[t1, t1] = K[t2, t2] = Ks
        fh[t1] = Ks * X
        B[3 * i, 0], B[3 * i + 1, t1], B[3 * i + 2, t2] = 1.0, 1.0, 1.0
    model = with_interface_layer(_model(M, K, B, fs, fh, np.eye(size)[[1]], A, gap), kn, kt)
    ref = PunchWear(k_n=tuple(kn * A), k_t=tuple(1.0 / (1.0 / Ks + 1.0 / (kt * A))), A=tuple(A), gap=tuple(gap),
                    mu=mu, X=X, N0=N0, k_w=k_w)
    return ref, model


# ------------------------------------------------------------------ (d) dynamic oscillator
@dataclass
class OscillatorWear:
    """(d): m ẍ + c ẋ + k x + f_pad = F cos ωt, a grounded Jenkins pad (k_t, μ) on the mass,
    normal load N = N₀ − k_n W, area A, Archard k_w. SI units, ω in rad/s."""

    m: float
    c: float
    k: float
    F: float
    omega: float
    k_t: float
    mu: float
    N0: float
    k_n: float
    A: float
    k_w: float

    def __post_init__(self):
        self._cache: dict = {}

    @property
    def delta0(self) -> float:
        return self.N0 / self.k_n

    @property
    def x_free(self) -> float:
        """|X| of the oscillator without the pad (μN = 0) (m)."""
        return float(self.F / abs(self.k - self.m * self.omega ** 2 + 1j * self.c * self.omega))

    @property
    def r0(self) -> float:
        """Final decay constant k_n k_w s(0)/A, s(0) = 4 X_free (1/cycle)."""
        return self.k_n * self.k_w * 4.0 * self.x_free / self.A

    def steady(self, N: float) -> dict:
        """The event-driven steady state at normal load N > 0: {amplitude (half peak-to-peak
        of the mass, m), slip (m/cycle), rate (m/cycle), stick_fraction, residual}."""
        key = float(N)
        if key in self._cache:
            return self._cache[key]
        from workflow.verification import timeint

        pads = timeint.Pads(dof=np.array([0]), k=np.array([self.k_t]), mu=self.mu, N0=np.array([N]),
                            cN=np.zeros((1, 1)))
        sys = timeint._Jenkins(np.array([[self.m]]), np.array([[self.c]]), np.array([[self.k]]),
                               np.array([self.F]), self.omega, pads)
        xs = sys.xs
        scale = np.array([xs, xs * self.omega, xs])
        z, res, _ = timeint._steady(lambda y: sys.period(y)[0], np.zeros(3), scale, 10, 400)
        T = 2 * np.pi / self.omega
        n0 = 2048
        ts = np.arange(n0) * T / n0
        _, x, stick = sys.period(z, ts)
        x = x[:, 0]
        dx = np.diff(np.r_[x, x[0]])
        turns = int(np.count_nonzero(np.sign(dx) != np.sign(np.roll(dx, 1))))
        if turns != 2:
            raise ValueError(f"oscillator: {turns} turning points per period at N = {N:g} N; the slip formula "
                             "needs one maximum and one minimum")
        ext = []
        for i, sgn in ((int(np.argmax(x)), 1.0), (int(np.argmin(x)), -1.0)):
            tf = np.linspace(ts[i] - T / n0, ts[i] + T / n0, 401)
            tf = np.mod(tf, T)
            order = np.argsort(tf)
            _, xf, _ = sys.period(z, tf[order])
            xx = np.empty(tf.size)
            xx[order] = xf[:, 0]
            j = int(np.argmax(sgn * xx))
            j = min(max(j, 1), tf.size - 2)
            y0, y1, y2 = sgn * xx[j - 1], sgn * xx[j], sgn * xx[j + 1]
            den = y0 - 2 * y1 + y2
            ext.append(sgn * (y1 - 0.125 * (y2 - y0) ** 2 / den if den < 0 else y1))
        amp = 0.5 * (ext[0] - ext[1])
        slip = float(jenkins_slip(N, amp, self.mu, self.k_t))
        out = {"amplitude": amp, "slip": slip, "rate": float(archard_rate(N, self.A, self.k_w, slip)),
               "stick_fraction": float(stick[0]), "residual": float(res)}
        self._cache[key] = out
        return out

    def rate_of_wear(self, W: float) -> float:
        N = self.N0 - self.k_n * W
        return self.steady(N)["rate"] if N > 0 else 0.0

    def march(self, W_stop: float = 0.99, tol: float = 1e-4, h0: float | None = None,
              max_steps: int = 400) -> dict:
        """Cycle jumps (Heun's RK2 in n) from W = 0 until W ≥ ``W_stop``·δ₀; local error
        ½h|r(W + h r) − r(W)| ≤ ``tol``·δ₀ per step. Returns {n (k,), W (k,), rate (k,), steps,
        rejected, evaluations}. Each rate is one event-driven steady state."""
        W, n = 0.0, 0.0
        r = self.rate_of_wear(W)
        if r <= 0:
            return {"n": np.array([0.0]), "W": np.array([0.0]), "rate": np.array([0.0]), "steps": 0,
                    "rejected": 0, "evaluations": 1}
        h = h0 or 0.01 * self.delta0 / r
        ns, Ws, rs, rejected = [0.0], [0.0], [r], 0
        while W < W_stop * self.delta0 and len(ns) <= max_steps:
            Wp = min(W + h * r, self.delta0 * (1 - 1e-9))
            rp = self.rate_of_wear(Wp)
            err = 0.5 * h * abs(rp - r)
            if err <= tol * self.delta0:
                W = W + 0.5 * h * (r + rp)
                n += h
                r = self.rate_of_wear(W)
                ns.append(n), Ws.append(W), rs.append(r)
            else:
                rejected += 1
            h *= min(4.0, max(0.2, 0.9 * math.sqrt(tol * self.delta0 / max(err, 1e-300))))
        return {"n": np.array(ns), "W": np.array(Ws), "rate": np.array(rs), "steps": len(ns) - 1,
                "rejected": rejected, "evaluations": len(self._cache)}

    def model(self):
        """ReducedModel, q = [x, n, t1, t2]: the mass (m, k, c, force F), a massless pad node
        on the tangential spring k_t to the mass (t1) and k_t grounded (t2, unloaded), normal
        spring k_n with static load −N₀. Observed: the mass. Tied frequency √((k + k_t)/m)."""
        K = np.zeros((4, 4))
        K[np.ix_([0, 2], [0, 2])] += self.k_t * np.array([[1.0, -1.0], [-1.0, 1.0]])
        K[0, 0] += self.k
        K[1, 1] = self.k_n
        K[3, 3] = self.k_t
        M = np.diag([self.m, 0.0, 0.0, 0.0])
        C = np.zeros((4, 4))
        C[0, 0] = self.c
        B = np.zeros((3, 4))
        B[:, 1:] = np.eye(3)
        fs = np.array([0.0, -self.N0, 0.0, 0.0])
        fh = np.array([self.F, 0.0, 0.0, 0.0])
        return _model(M, K, B, fs, fh, np.array([[1.0, 0.0, 0.0, 0.0]]), [self.A], [0.0], C=C)
