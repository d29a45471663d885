"""Lumped-parameter references for the mistuned bladed disk with friction (issue 50, checks).

Independent of the project's cyclic / whole-disk code: dense matrices, a direct
solve per frequency, and (part 3) the event-driven integrator of
:mod:`workflow.verification.timeint`. Units SI throughout (kg, N/m, N s/m, N, m,
rad/s); frequencies ω in rad/s unless a name ends in ``_hz``.

1. **One-family lumped bladed disk** (:func:`matrices`) — the two-DOF-per-sector
   model of Griffin & Hoosac (J. H. Griffin, T. M. Hoosac, "Model development and
   statistical investigation of turbine blade mistuning", J. Vib. Acoust. Stress
   Reliab. Des. 106 (1984) 204–210): sector s has a blade mass m_b on a blade spring
   ``k_b (1 + δ_s)`` to a disk mass m_d; the disk mass sits on a ground spring k_d,
   and neighbouring disk masses are coupled by k_c around the ring (periodic).
   Damping is light viscous, stiffness-proportional on the *tuned* stiffness,
   ``C = (2ζ/ω_b) K(δ = 0)`` with ω_b = √(k_b/m_b): modal damping ratio ζ·ω_r/ω_b
   (≈ 0.8 ζ on the blade family of the defaults), the same for every mistuning
   pattern — mistuning is in stiffness (frequency) only, as Whitehead assumes.
   Engine-order excitation on the blades, ``F_s = F exp(i s 2π EO/N)``
   (:func:`forcing`). The amplification factor (:func:`amplification_factor`) is
   the largest blade peak of the mistuned disk over the blade-dominated family's
   band divided by the tuned peak, the latter from the EO nodal-diameter sector
   model (:func:`sector_matrices`, cyclic symmetry) — so ``AF(δ = 0) = 1`` checks
   the full model against its own cyclic reduction. Whitehead's upper bound for
   one family of modes: ``(1 + √N)/2`` (D. S. Whitehead, "Effect of mistuning on
   the vibration of turbo-machine blades induced by wakes", J. Mech. Eng. Sci. 8
   (1966) 15–21; "The maximum factor by which forced vibration of blades can
   increase due to mistuning", J. Eng. Gas Turbines Power 120 (1998) 115–119).
   It assumes a single family: where a disk-dominated family veers into the blade
   family it can be exceeded (Kenyon, Griffin & Kim, J. Propulsion Power 20 (2004)
   863–870; review: Castanier & Pierre, J. Propulsion Power 22 (2006) 384–396);
   the defaults keep the disk family ≥ 50 % above the blade family
   (:func:`blade_band` refuses a band that reaches it).

2. **Monte Carlo** (:func:`monte_carlo`, :func:`sigma_scan`) of AF over random
   Gaussian patterns δ ~ N(0, σ²) from a seeded :class:`numpy.random.Generator`, and a
   gradient-free worst-pattern search (:func:`worst_pattern`, a (1+1) evolution
   strategy in a box |δ_s| ≤ a, in the spirit of Petrov & Ewins, "Analysis of the
   worst mistuning patterns in bladed disk assemblies", J. Turbomach. 125 (2003)
   623–631). Measured on the defaults (max AF over 100 patterns per σ, σ = 0.0025…0.08,
   seed 1): N = 12 — 1.63 (EO 1, σ = 0.03–0.05), 0.73 of Whitehead's 2.23; N = 24 — 1.65
   (EO 3, σ = 0.02), 0.56 of 2.95; the worst σ is 0.01–0.03, about the blade family's 1.2 %
   frequency spread. The worst-pattern search (300 evaluations, box ±0.04) reaches 1.77
   (0.79 of the bound) at N = 12 EO 1 and 1.84 (0.62) at N = 24 EO 3.

   Limits. σ → 0: once σ is below the mode spacing mistuning is a regular perturbation and
   AF − 1 is first order in σ. k_c → ∞ does *not* simply mean "strong coupling" here: the
   ring becomes rigid, the disk stops moving in every ND ≥ 1, and those blade modes all tend
   to ω_b (blades clamped on an immobile disk) — a degenerate family that any mistuning
   localises (EO 3, N = 12, σ = 0.003: max AF − 1 over 5 patterns 0.04 at k_c = k_b, 0.41
   at 100 k_b). For EO = 0 the ND-0 mode stays isolated below them, and AF → 1 + O(σ)
   (AF − 1 ≈ 5σ at k_c ≥ 10 k_b against 0.25 at σ = 0.003 on the weak default ring).

3. **Two mistuned blades with friction** (:func:`two_blade_system`): two blades
   (mass m each, blade springs k_1 ≠ k_2 to the rigid disk), coupled by k_c,
   each held at its root by a Jenkins element (tangential stiffness k_t in series
   with a Coulomb slider of limit μN, N constant), harmonic force
   ``F cos(ωt + s π EO)`` on blade s = 0, 1 (EO phase of N = 2 sectors: in phase for
   even EO, in antiphase for odd EO — real, so the engine's real cos(ωt) load
   carries it). :func:`two_blade_time` is the event-driven reference
   (:func:`workflow.verification.timeint.jenkins_steady_state`), :func:`two_blade_model`
   the same system as a :class:`workflow.engine.model.ReducedModel`
   (:func:`workflow.verification.models.jenkins`), :func:`two_blade_hb` the project's
   HB on it through :func:`workflow.verification.runner.hb_first_harmonic` (the
   engine's front door) and :func:`two_blade_errors` the comparison.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.optimize import minimize_scalar

# ------------------------------------------------------------------ defaults (SI)
#: blade modal mass (kg) and blade-alone frequency 500 Hz: a small turbine blade's first flap
M_B = 0.2
K_B = M_B * (2 * np.pi * 500.0) ** 2          # 1.97e6 N/m
#: disk mass per sector (kg), disk ground spring: the disk family (≥ 624 Hz) well above the
#: blade family (≈ 400 Hz) — one family of blade-dominated modes
M_D = 1.0
K_D = 5.0 * K_B
#: ring coupling: small against k_b so the blade family is a narrow veering band (ND 0…N/2
#: within ≈ 1 % in frequency for N = 12–24), comparable to the frequency spread of σ = 2–5 %
#: stiffness mistuning — the regime where mistuning localises the response
K_C = 0.05 * K_B
#: damping ratio at ω_b (C = 2ζ/ω_b K_tuned)
ZETA = 0.002
DEFAULTS = dict(m_b=M_B, k_b=K_B, m_d=M_D, k_d=K_D, k_c=K_C, zeta=ZETA)

#: blade band margin beyond the family's lowest/highest undamped frequency (relative):
#: 10 ζ, ten half-power half-widths — a peak is within a few ζ of its natural frequency
BAND_MARGIN = 10 * ZETA
#: the frequency grid's relative step h for the peak search: ζ/4 (pass a smaller ``step`` to
#: :func:`blade_peaks` for a lighter-damped model). A resonance of damping ratio ζ_r ≥ 0.8 ζ
#: sampled at most h/2 off its peak reads ≥ 1/√(1 + (h/(2ζ_r))²) ≈ 1 − 1.2 % of it; every grid
#: maximum within :data:`REFINE_WINDOW` of the best is refined.
GRID_STEP = ZETA / 4
#: grid maxima refined: those within 5 % of the blade's best grid value (4× the grid's bound)
REFINE_WINDOW = 0.05
#: relative frequency tolerance of the bounded scalar refinement (Brent)
XATOL_REL = 1e-9
#: the peak amplitude's relative resolution: Brent stops within xatol + √ε|ω|/3 ≈ 6e-9 ω of the
#: peak, and a frequency error δ off a peak of damping ratio ζ_r costs ½(δ/ζ_r)² ≈
#: ½(6e-9/1.6e-3)² ≈ 7e-12 with the defaults (measured: full model vs sector model ≤ 1.4e-11),
#: plus the solve's round-off (cond(D) ε ≈ 1e-13 at resonance). Stated with margin:
PEAK_RTOL = 1e-9


def whitehead_bound(n_sectors: int) -> float:
    """Whitehead's (1966) largest amplification factor of one mode family, ``(1 + √N)/2``."""
    return 0.5 * (1.0 + np.sqrt(float(n_sectors)))


# ------------------------------------------------------------ 1. the lumped disk
def _spring(K: np.ndarray, a: int, b: int, k: float) -> None:
    K[np.ix_([a, b], [a, b])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])


def _stiffness(n: int, delta, k_b: float, k_d: float, k_c: float) -> np.ndarray:
    K = np.zeros((2 * n, 2 * n))
    for s in range(n):
        _spring(K, s, n + s, k_b * (1.0 + delta[s]))
        K[n + s, n + s] += k_d
        if n > 1:
            _spring(K, n + s, n + (s + 1) % n, k_c)   # N = 2: the two disks coupled twice
    return K


def matrices(n_sectors: int, mistuning=None, *, m_b: float = M_B, k_b: float = K_B, m_d: float = M_D,
             k_d: float = K_D, k_c: float = K_C, zeta: float = ZETA) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, K, C) of the N-sector lumped disk, dense real (2N × 2N), DOFs ``[blades 0…N−1, disks 0…N−1]``.

    ``mistuning``: δ (N,), blade s's spring is ``k_b (1 + δ_s)`` (None: tuned). Masses kg,
    stiffnesses N/m; ``C = (2ζ/ω_b) K_tuned`` (N s/m), ω_b = √(k_b/m_b).
    """
    n = int(n_sectors)
    delta = np.zeros(n) if mistuning is None else np.asarray(mistuning, float)
    if delta.shape != (n,):
        raise ValueError(f"mistuning has shape {delta.shape}, expected ({n},)")
    M = np.diag(np.concatenate([np.full(n, m_b), np.full(n, m_d)]))
    K = _stiffness(n, delta, k_b, k_d, k_c)
    C = 2.0 * zeta / np.sqrt(k_b / m_b) * _stiffness(n, np.zeros(n), k_b, k_d, k_c)
    return M, K, C


def forcing(n_sectors: int, engine_order: int, force: float = 1.0) -> np.ndarray:
    """Complex load amplitude (2N,) in N: ``F exp(i s 2π EO/N)`` on blade s, nothing on the disks."""
    n = int(n_sectors)
    f = np.zeros(2 * n, complex)
    f[:n] = force * np.exp(2j * np.pi * engine_order * np.arange(n) / n)
    return f


def sector_matrices(n_sectors: int, engine_order: int, *, m_b: float = M_B, k_b: float = K_B, m_d: float = M_D,
                    k_d: float = K_D, k_c: float = K_C, zeta: float = ZETA):
    """(M, K, C) (2 × 2, DOFs [blade, disk]) of the tuned disk's EO nodal diameter.

    Cyclic symmetry: with ``x_s = X e^{i s φ}``, φ = 2π EO/N, the ring term
    ``k_c (2x_s − x_{s+1} − x_{s−1})`` is ``2 k_c (1 − cos φ) X`` — a real sector model.
    """
    phi = 2 * np.pi * engine_order / n_sectors
    kr = k_d + 2.0 * k_c * (1.0 - np.cos(phi))    # N = 2: both ring springs join the same two disks
    K = np.array([[k_b, -k_b], [-k_b, k_b + kr]])
    return np.diag([m_b, m_d]), K, 2.0 * zeta / np.sqrt(k_b / m_b) * K


def forced_response(M, K, C, f, omegas, chunk: int = 256) -> np.ndarray:
    """Complex steady-state amplitudes (n_ω, n) of ``M ẍ + C ẋ + K x = Re(f e^{iωt})``: one dense
    solve of ``(K − ω²M + iωC) X = f`` per frequency (ω rad/s, X m), in batches of ``chunk``."""
    w = np.atleast_1d(np.asarray(omegas, float))
    f = np.asarray(f, complex)
    out = np.empty((len(w), len(f)), complex)
    for i in range(0, len(w), chunk):
        ww = w[i:i + chunk, None, None]
        D = K[None] - ww ** 2 * M[None] + 1j * ww * C[None]
        out[i:i + chunk] = np.linalg.solve(D, np.broadcast_to(f, (len(ww), len(f)))[..., None])[..., 0]
    return out


def blade_band(M, K, n_blades: int, margin: float = BAND_MARGIN) -> tuple[float, float]:
    """(ω_lo, ω_hi) rad/s around the lowest ``n_blades`` undamped frequencies (the blade family),
    widened by ``margin`` (relative); ValueError if the next family is inside it (not one family)."""
    w = np.sqrt(np.abs(sla.eigh(K, M, eigvals_only=True)))
    lo, hi = w[0] * (1 - margin), w[n_blades - 1] * (1 + margin)
    if len(w) > n_blades and w[n_blades] <= hi * (1 + margin):
        raise ValueError(f"the blade family (up to {w[n_blades - 1]:.6g} rad/s) is not separated from the next "
                         f"mode ({w[n_blades]:.6g} rad/s): not a one-family model")
    return float(lo), float(hi)


@dataclass
class Peaks:
    """Largest |amplitude| (m) of each observed DOF over a band and the frequency (rad/s) it is at."""

    amplitude: np.ndarray
    omega: np.ndarray


def _grid(band, step: float) -> np.ndarray:
    lo, hi = band
    n = int(np.ceil(np.log(hi / lo) / step)) + 1
    return np.geomspace(lo, hi, max(n, 3))


def _refine(M, K, C, f, dof: int, a: float, b: float) -> tuple[float, float]:
    """Bounded Brent on −|X_dof(ω)| in [a, b]: (ω*, |X_dof(ω*)|)."""
    def neg(w):
        return -abs(np.linalg.solve(K - w * w * M + 1j * w * C, f)[dof])
    r = minimize_scalar(neg, bounds=(a, b), method="bounded", options={"xatol": XATOL_REL * a})
    return float(r.x), float(-r.fun)


def blade_peaks(M, K, C, f, band, *, blades=None, step: float = GRID_STEP, only_largest: bool = False) -> Peaks:
    """Each blade's largest |X| (m) over ``band`` (rad/s): a geometric grid of relative step
    ``step``, then each grid maximum within :data:`REFINE_WINDOW` of the blade's best refined by
    a bounded scalar search to :data:`XATOL_REL` in frequency (peak to :data:`PEAK_RTOL`).

    ``blades``: the observed DOFs (default the first half, the blades of :func:`matrices`).
    A grid maximum at a band edge is kept unrefined (the peak is then outside the band).
    ``only_largest``: refine only the blades whose grid peak is within :data:`REFINE_WINDOW` of the
    largest blade's (the others keep their grid value, a lower bound) — enough for the largest
    blade peak, :func:`amplification_factor`, at a fraction of the cost.
    """
    M, K, C = (np.asarray(a, float) for a in (M, K, C))
    f = np.asarray(f, complex)
    blades = np.arange(M.shape[0] // 2) if blades is None else np.atleast_1d(blades)
    w = _grid(band, step)
    A = np.abs(forced_response(M, K, C, f, w)[:, blades])
    amp, at = np.empty(len(blades)), np.empty(len(blades))
    top = A.max()
    for j, dof in enumerate(blades):
        a = A[:, j]
        best, w_best = a.max(), w[a.argmax()]
        inner = np.flatnonzero((a[1:-1] >= a[:-2]) & (a[1:-1] >= a[2:])) + 1
        if only_largest and best < (1 - REFINE_WINDOW) * top:
            inner = inner[:0]
        for i in inner[a[inner] >= (1 - REFINE_WINDOW) * best]:
            wi, ai = _refine(M, K, C, f, int(dof), w[i - 1], w[i + 1])
            if ai > best:
                best, w_best = ai, wi
        amp[j], at[j] = best, w_best
    return Peaks(amp, at)


def tuned_peak(n_sectors: int, engine_order: int, force: float = 1.0, **params) -> Peaks:
    """The tuned disk's blade peak (m) from its EO sector model (:func:`sector_matrices`)."""
    p = {**DEFAULTS, **params}
    M, K, C = sector_matrices(n_sectors, engine_order, **p)
    return blade_peaks(M, K, C, np.array([force, 0.0]), blade_band(M, K, 1), blades=[0])


def mistuned_peaks(n_sectors: int, mistuning, engine_order: int, force: float = 1.0, *,
                   only_largest: bool = False, **params) -> Peaks:
    """Each blade's peak (m) of the mistuned disk over its own blade-family band
    (``only_largest``: see :func:`blade_peaks`)."""
    M, K, C = matrices(n_sectors, mistuning, **{**DEFAULTS, **params})
    return blade_peaks(M, K, C, forcing(n_sectors, engine_order, force), blade_band(M, K, n_sectors),
                       only_largest=only_largest)


def amplification_factor(n_sectors: int, mistuning, engine_order: int, *, tuned: float | None = None,
                         **params) -> float:
    """max over blades of the mistuned peak / the tuned peak (dimensionless).

    ``tuned``: the tuned peak (m) if already known (:func:`tuned_peak`), for Monte Carlo loops.
    """
    t = tuned_peak(n_sectors, engine_order, **params).amplitude[0] if tuned is None else tuned
    return float(mistuned_peaks(n_sectors, mistuning, engine_order, only_largest=True, **params).amplitude.max() / t)


# --------------------------------------------------------------- 2. Monte Carlo
def monte_carlo(n_sectors: int, sigma: float, n_patterns: int, engine_order: int, *, seed: int = 0,
                **params) -> np.ndarray:
    """AF (n_patterns,) of patterns δ ~ N(0, σ²) i.i.d. per blade from ``default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    t = tuned_peak(n_sectors, engine_order, **params).amplitude[0]
    return np.array([amplification_factor(n_sectors, rng.normal(0.0, sigma, n_sectors), engine_order,
                                          tuned=t, **params) for _ in range(n_patterns)])


def sigma_scan(n_sectors: int, sigmas, n_patterns: int, engine_order: int, *, seed: int = 0,
               **params) -> np.ndarray:
    """AF (len(sigmas), n_patterns): :func:`monte_carlo` at each σ. The *same* unit patterns are
    scaled by each σ (common random numbers), so the σ-dependence is not sampling noise."""
    rng = np.random.default_rng(seed)
    unit = rng.normal(0.0, 1.0, (n_patterns, n_sectors))
    t = tuned_peak(n_sectors, engine_order, **params).amplitude[0]
    return np.array([[amplification_factor(n_sectors, s * u, engine_order, tuned=t, **params) for u in unit]
                     for s in sigmas])


def worst_pattern(n_sectors: int, bound: float, engine_order: int, *, start=None, evaluations: int = 200,
                  seed: int = 0, **params) -> tuple[np.ndarray, float, np.ndarray]:
    """A (1+1) evolution strategy for the pattern of largest AF in the box |δ_s| ≤ ``bound``.

    Starts from ``start`` (clipped to the box; default random uniform), perturbs all blades by
    N(0, s²) clipped to the box, keeps a better pattern; the step s (initially bound/2) follows
    Rechenberg's 1/5 success rule. Returns (pattern, its AF, AF history per evaluation). A
    local search: a lower bound of the worst case, not the worst case.
    """
    rng = np.random.default_rng(seed)
    t = tuned_peak(n_sectors, engine_order, **params).amplitude[0]
    af = lambda d: amplification_factor(n_sectors, d, engine_order, tuned=t, **params)  # noqa: E731
    x = np.clip(rng.uniform(-bound, bound, n_sectors) if start is None else np.asarray(start, float), -bound, bound)
    best, step, hist, wins = af(x), 0.5 * bound, [], []
    for _ in range(evaluations):
        y = np.clip(x + rng.normal(0.0, step, n_sectors), -bound, bound)
        a = af(y)
        wins.append(a > best)
        if a > best:
            x, best = y, a
        hist.append(best)
        if len(wins) == 10:       # 1/5 rule over the last 10 trials
            step *= 1.5 if sum(wins) > 2 else 0.6
            step = min(step, bound)
            wins = []
    return x, float(best), np.array(hist)


# ------------------------------------------- 3. two mistuned blades with friction
@dataclass(frozen=True)
class TwoBlade:
    """The two-blade friction model (SI).

    m kg; k1, k2 blade springs N/m (k2 = 1.04 k1: 4 % mistuning); kc coupling N/m;
    kt the Jenkins tangential stiffness N/m; mu, normal N (slip force μN = 50 N); zeta the
    damping ratio at the first tied mode (C = 2ζ/ω_t K, structure only); force N per blade;
    engine_order: blade 1 is loaded with the phase e^{iπ EO} = ±1.
    """

    m: float = 0.1
    k1: float = 1.0e6
    k2: float = 1.04e6
    kc: float = 5.0e4
    kt: float = 5.0e5
    mu: float = 0.5
    normal: float = 100.0
    zeta: float = 0.005
    force: float = 8.0
    engine_order: int = 1


def two_blade_system(p: TwoBlade = TwoBlade()):
    """(M, C, K, f, pads) of :class:`TwoBlade`: structure DOFs [blade 0, blade 1] and their
    grounded Jenkins pads (:class:`workflow.verification.timeint.Pads`, constant normal load)."""
    from workflow.verification.timeint import Pads

    K = np.array([[p.k1 + p.kc, -p.kc], [-p.kc, p.k2 + p.kc]])
    M = p.m * np.eye(2)
    C = 2.0 * p.zeta / two_blade_tied(p)[0] * K
    f = p.force * np.array([1.0, np.cos(np.pi * p.engine_order)])
    pads = Pads(dof=np.array([0, 1]), k=np.full(2, p.kt), mu=p.mu, N0=np.full(2, p.normal), cN=np.zeros((2, 2)))
    return M, C, K, f, pads


def two_blade_tied(p: TwoBlade = TwoBlade()) -> np.ndarray:
    """The two natural frequencies (rad/s) with the pads stuck (k_t to ground on each blade)."""
    K = np.array([[p.k1 + p.kc + p.kt, -p.kc], [-p.kc, p.k2 + p.kc + p.kt]])
    return np.sqrt(np.linalg.eigvalsh(K / p.m))


def two_blade_time(p: TwoBlade, omegas) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Event-driven reference at each ω (rad/s): (first-harmonic amplitudes (n_ω, 2) m, stick
    fractions (n_ω, 2), seconds (n_ω,)). Stick/slip switches exactly at events (DOP853,
    rtol 1e-11); the state is periodic to :data:`~workflow.verification.timeint.PERIODIC_TOL`
    (shooting, then marching period by period), so |X₁| is good to ~5e-7 relative
    (the bound measured for the 2-DOF damper in ``tests/workflow/test_verification.py``)."""
    from workflow.verification.timeint import jenkins_steady_state

    M, C, K, f, pads = two_blade_system(p)
    amp, stick, secs = [], [], []
    for w in np.atleast_1d(omegas):
        t0 = time.perf_counter()
        s = jenkins_steady_state(M, C, K, f, float(w), pads)
        amp.append(s.first)
        stick.append(s.stick_fraction)
        secs.append(time.perf_counter() - t0)
    return np.array(amp), np.array(stick), np.array(secs)


def two_blade_model(p: TwoBlade = TwoBlade(), blade: int = 0):
    """The same system as the engine sees it: a :class:`workflow.engine.model.ReducedModel` with two
    contact pairs (the pads: massless nodes, DOFs n, t1, t2; B picks them), observing ``blade``."""
    from workflow.verification.models import jenkins

    M, C, K, f, pads = two_blade_system(p)
    model, _ = jenkins(M, C, K, f, 0, pads, "two-blade")
    O = np.zeros_like(model.O)
    O[0, blade] = 1.0
    return dataclasses.replace(model, O=O)


def two_blade_hb(p: TwoBlade, omegas, nh: int, nit: int | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The project's HB (HBM, Nh harmonics, ``nit`` DLFT time samples — None: the engine's default
    :func:`workflow.engine.fourier.default_nit` — and the default penalty) at each ω (rad/s):
    (first-harmonic amplitudes (n_ω, 2) m, converged (n_ω,), seconds). One engine run per
    blade: the engine reports the norm over the observed DOFs."""
    from workflow.engine.fourier import default_nit
    from workflow.verification.runner import hb_first_harmonic

    t0 = time.perf_counter()
    fhz = np.atleast_1d(np.asarray(omegas, float)) / (2 * np.pi)
    amp, ok = [], []
    for b in (0, 1):
        a, c, _ = hb_first_harmonic(two_blade_model(p, b), fhz, mu=p.mu, nh=nh, nit=nit or default_nit(nh))
        amp.append(a)
        ok.append(c)
    return np.array(amp).T, np.logical_and(*ok), time.perf_counter() - t0


#: the check's points: (name, force N, ω / ω_tied,2) — ω_tied,2 the upper tied mode (antiphase,
#: the EO = 1 mode). "micro": F = 8 N, both pads stuck 77–83 % of the period near the tied
#: resonance (a single Jenkins element has no true micro-slip: "low slip share");
#: "macro": F = 100 N, pads slipping 80–90 % of the period around the friction-damped peak
#: (≈ 0.84 ω_tied,2, between the free and the tied modes)
TWO_BLADE_POINTS = (("micro", 8.0, (0.98, 1.0)), ("macro", 100.0, (0.82, 0.84, 0.86)))

#: error budget of the engine's HB against the event-driven reference (relative, first harmonic):
#: ``GRID_C (2π/nit)² + TRUNC_C Nh⁻⁴ + REF_ERR`` (:func:`hb_error_budget`)
GRID_C, TRUNC_C, REF_ERR = 0.5, 0.4, 1e-6


def hb_error_budget(nh: int, nit: int) -> float:
    """Relative first-harmonic error the engine's HB may have on the two-blade model.

    * DLFT time grid: the DLFT works on nit samples, so a stick ↔ slip switch is placed to
      within Δτ = 2π/nit; the Jenkins force is continuous with a slope jump there, so the
      misplaced area, and the first harmonic's error, is O(Δτ²): ``GRID_C (2π/nit)²``.
    * HB truncation: the force's harmonics decay like j⁻² (C⁰ with slope jumps), the
      structure divides harmonic j by ≈ (jω)² m, so the neglected displacement harmonics
      fall like j⁻⁴: ``TRUNC_C Nh⁻⁴``.
    * The reference: ``REF_ERR`` (events exact, DOP853 rtol 1e-11, periodic to 1e-7).

    The rates are derived; the constants are the measured worst cases over
    :data:`TWO_BLADE_POINTS` and both blades with a margin of about 2. Grid, Nh = 7: 2.2e-3 at
    nit = 64 (its term 4.8e-3), 1.9e-4 at 256 (3.0e-4; not monotone in nit between 128 and
    512: where the switches fall between samples matters). Truncation, at nit = 4096 where the
    grid term is 1e-6: 7.1e-5 at Nh = 7 (its term 1.7e-4), 3.7e-6 at 15 (7.9e-6) — a factor 19
    for (15/7)⁴ = 21 — and ≤ 6e-7 at 31 (the reference's level).
    """
    return GRID_C * (2 * np.pi / nit) ** 2 + TRUNC_C * float(nh) ** -4 + REF_ERR


def two_blade_errors(nhs=(7, 15), points=TWO_BLADE_POINTS, p: TwoBlade = TwoBlade(),
                     nit: int | None = None) -> list[dict]:
    """Rows (level, force, ratio, omega, Nh, nit, blade, hb, reference, error, budget, converged,
    stick, seconds_hb, seconds_ref) of the engine's HB against the time integration.

    ``error`` = |A_HB − A_ref| / A_ref per blade; ``budget`` = :func:`hb_error_budget` — what
    bounds it is the DLFT's time grid (nit) and the HB truncation (Nh); the reference's time
    stepping adds nothing beyond ~1e-6 (event-driven, no fixed step). ``nit`` None: the
    engine's default, 4(2Nh + 1) rounded up to a power of 2 (64 at Nh = 7).
    Measured with the defaults (max over blades and points; HB seconds per point, 2 runs):
    Nh = 3: 2.8e-3 (nit 64, 0.2 s); 7: 2.2e-3 (64, 0.1 s); 15: 9.0e-4 (128, 0.15 s); 31: 2.2e-4
    (256, 0.5 s) — at Nh ≥ 7 the default grid, not Nh, is the error: at nit = 1024, Nh = 7:
    6.3e-5, 15: 8.9e-6. The references take 0.9–1.6 s a point (one core).
    """
    from workflow.engine.fourier import default_nit

    rows = []
    for level, force, ratios in points:
        q = dataclasses.replace(p, force=force)
        ws = two_blade_tied(q)[1] * np.asarray(ratios)
        ref, stick, t_ref = two_blade_time(q, ws)
        for nh in nhs:
            n_t = nit or default_nit(nh)
            amp, ok, t_hb = two_blade_hb(q, ws, nh, n_t)
            for i, (r, w) in enumerate(zip(ratios, ws)):
                for b in (0, 1):
                    rows.append(dict(level=level, force=force, ratio=float(r), omega=float(w), Nh=int(nh), nit=n_t,
                                     blade=b, hb=float(amp[i, b]), reference=float(ref[i, b]),
                                     error=float(abs(amp[i, b] - ref[i, b]) / ref[i, b]),
                                     budget=hb_error_budget(nh, n_t), converged=bool(ok[i]),
                                     stick=float(stick[i, b]), seconds_hb=t_hb / len(ws), seconds_ref=float(t_ref[i])))
    return rows
