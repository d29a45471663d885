"""Linear limits of the friction interface: tied modes, the band, tied, sliding and stuck FRFs.

The friction-damped response lies between the interface *stuck* (the pairs in contact in the
static state held, μ → ∞) and *sliding* (μ = 0, normal contact kept) linear responses; *tied*
(u_r = 0 at every pair) glues the separated pairs too. The first tied mode the tip load
excites and the tip observes sets the default band (±10 %).
"""
from __future__ import annotations

import time
import warnings

import numpy as np
import scipy.linalg

from workflow.engine.errors import BundleError, SceneError


def condensed(rc, omega: float, nh: int, **kw):
    """:func:`workflow.engine.condense.condense` of ``rc`` at ``omega`` (rad/s), harmonics 0…``nh``,
    on every core for a large interface (:func:`workflow.engine.blas.large_blas`): the engine
    runs its sweeps on one BLAS thread (small dense systems), and the condensation inside
    them — the ε-, Nh- and reference checks, the peak search, the frequency steps — took it
    along. 512 pairs, Nh = 7: 3.0 → 1.8–2.0 s a frequency, with dZr/dω 16.2 → 8.7 s."""
    from workflow.engine.condense import condense
    from workflow.engine.blas import large_blas

    with large_blas(int(rc.n_rel)):
        return condense(rc, omega, nh, **kw)


#: The band's condensations are all kept in memory while they take at most this many bytes
#: (:class:`CondensedGrid`), else made when a sweep reaches their frequency. At 512 pairs and
#: Nh = 7 one frequency's Z_r is 302 MB: 50 points would hold 15 GB.
KEEP_BYTES = 2 * 1024 ** 3
#: condensations an on-demand grid keeps besides the one in use (a sweep's way back, the
#: second pass, revisits a point's neighbours)
KEEP_RECENT = 2


class CondensedGrid:
    """The condensations of a band (:func:`condensed` at each of ``omegas`` [rad/s], harmonics
    0…``nh``), indexed like the list of them that the sweeps read.

    All are kept once made while they fit in :data:`KEEP_BYTES`; above, each is made when a
    sweep asks for it and only the last :data:`KEEP_RECENT` + 1 stay (the variants then pay
    one condensation a point each, measured at 512 pairs, Nh = 7: 0.57 s against ~2 s of
    solving). ``omegas`` never condenses; ``seconds``: the condensation time spent so far
    (reported apart from the sweeps, which subtract it).
    Measured (interface-scaling bench, 512 pairs, HBM Nh = 7, 17 points): peak memory
    6.98 GB with the band held whole."""

    def __init__(self, rc, omegas, nh: int, keep_bytes: float | None = None):
        self.rc, self.nh = rc, int(nh)
        self.omegas = np.asarray(omegas, dtype=float).copy()
        r = int(rc.n_rel)
        per = (self.nh + 1) * (r * r + r) * 16
        self.keep_all = len(self.omegas) * per <= (KEEP_BYTES if keep_bytes is None else keep_bytes)
        self._kept: dict = {}
        self._clock = [0.0]         # shared with the grid's slices

    @property
    def seconds(self) -> float:
        """Condensation time [s] spent by this grid and its slices."""
        return self._clock[0]

    def __len__(self) -> int:
        return len(self.omegas)

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    def __getitem__(self, i):
        if isinstance(i, slice):
            idx = range(len(self))[i]
            sub = CondensedGrid(self.rc, self.omegas[i], self.nh, keep_bytes=0.0)
            sub.keep_all, sub._clock = self.keep_all, self._clock
            sub._kept = {k: self._kept[j] for k, j in enumerate(idx) if j in self._kept}
            return sub
        i = range(len(self))[i]
        c = self._kept.pop(i, None)
        if c is None:
            t = time.perf_counter()
            c = condensed(self.rc, float(self.omegas[i]), self.nh, derivative=False)
            self._clock[0] += time.perf_counter() - t
        self._kept[i] = c           # the most recent last
        if not self.keep_all:
            while len(self._kept) > KEEP_RECENT + 1:
                del self._kept[next(iter(self._kept))]
        return c


#: a tied mode is "excited" if its modal response at the observed DOFs is at
#: least this fraction of the largest one.
SIGNIFICANT = 0.05


def tied_modes(rc) -> tuple[np.ndarray, np.ndarray]:
    """Eigenfrequencies (Hz) of the model with the interface tied (u_r = 0), and
    each mode's modal response at the observed DOFs to the harmonic load,
    ``‖O φ‖ |φᴴ f| / ω²`` (m), normalised so the largest is 1. K, M may be
    complex Hermitian (a cyclic ND's sector model: harmonic 1's ND)."""
    from workflow.engine.condense import RelativeCoordinates, tied_basis

    r = rc.n_rel
    tb = tied_basis(rc) if isinstance(rc, RelativeCoordinates) else None
    if tb is not None and tb.mu.max() > 0:
        # the condensation's modes (Φᵀ K_yy Φ = I, μ = 1/ω², ascending μ): not solved again, and the
        # low modes more accurate than eigh(K_yy, M_yy)'s (512 pairs: the first tied ω² 1.6e-7 off
        # there, 6e-13 here, against its Rayleigh quotient after inverse iteration). For the
        # M-normalised ψ = Φ/√μ, ‖Oψ‖ |ψᵀf| / ω² = ‖OΦ‖ |Φᵀf|. Massless coordinates (a lumped
        # model's light nodes, an interface layer's springs) have μ = 0 to round-off: no mode.
        keep = tb.mu > 1e-14 * tb.mu.max()
        phi, w2 = tb.Phi[:, keep][:, ::-1], 1.0 / tb.mu[keep][::-1]
        resp = np.linalg.norm(rc.O[:, r:] @ phi, axis=0) * np.abs(phi.T @ rc.f_harmonic[r:])
    else:
        w2, phi = scipy.linalg.eigh(rc.K[r:, r:], rc.M[r:, r:])
        w2 = np.maximum(w2, 0.0)
        obs = np.linalg.norm(rc.O[:, r:] @ phi, axis=0)
        force = np.abs(phi.conj().T @ rc.f_harmonic[r:])
        with np.errstate(divide="ignore", invalid="ignore"):
            resp = np.where(w2 > 0, obs * force / np.where(w2 > 0, w2, 1.0), 0.0)
    f = np.sqrt(w2) / (2 * np.pi)
    top = resp.max() if resp.size and resp.max() > 0 else 1.0
    return f, resp / top


def first_excited_mode(rc) -> tuple[float, int]:
    """(frequency in Hz, index) of the first tied mode significantly excited and observed."""
    try:
        f, s = tied_modes(rc)
    except np.linalg.LinAlgError:
        raise BundleError("reduced model: the structure with the interface tied has a singular mass matrix "
                          "(massless DOFs only): it has no tied mode; give the band (sweep.f_start_hz, "
                          "sweep.f_stop_hz)") from None
    idx = np.flatnonzero((s >= SIGNIFICANT) & (f > 0))
    if not idx.size:
        raise BundleError("reduced model: no tied mode responds at the observed DOFs to the harmonic load "
                          "(f_harmonic or O is zero?)")
    return float(f[idx[0]]), int(idx[0])


def band(f_start_hz: float, f_stop_hz: float, f_mode: float) -> tuple[float, float]:
    """(f_start, f_stop) in Hz; a bound of 0 means ∓10 % of ``f_mode``."""
    f0 = f_start_hz or 0.9 * f_mode
    f1 = f_stop_hz or 1.1 * f_mode
    if f1 <= f0:
        raise SceneError(f"sweep: band [{f0:g}, {f1:g}] Hz is empty (sweep.f_start_hz / sweep.f_stop_hz; "
                         f"first tied bending frequency {f_mode:g} Hz)")
    return float(f0), float(f1)


def _solve_or_inf(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A⁻¹ b``, or inf where ``A`` is singular to working precision (an
    undamped resonance exactly on a frequency point: no bounded response)."""
    if b.size == 0:
        return b.astype(complex)
    # LAPACK's estimate of the reciprocal 1-norm condition from the LU it solves with: an SVD
    # for cond(A) took 8 s of a 512-pair sweep's 190 (64 ms a point)
    with warnings.catch_warnings():     # exactly singular: rcond = 0 below says so
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        lu, piv = scipy.linalg.lu_factor(A, check_finite=False)
    gecon, = scipy.linalg.lapack.get_lapack_funcs(("gecon",), (lu,))
    rcond, info = gecon(lu, float(np.linalg.norm(A, 1)))
    if info != 0 or not rcond > 1e-14:
        return np.full(b.shape, np.inf, dtype=complex)
    return scipy.linalg.lu_solve((lu, piv), b, check_finite=False)


def _held(static) -> tuple[np.ndarray, np.ndarray]:
    """(sliding, stuck) masks of the relative DOFs held at u = 0 about the static state: the
    normal DOF of every pair in contact (sliding), or its three DOFs (stuck); a separated pair
    is free in both."""
    closed = np.repeat(static.state != 0, 3)
    normal = np.zeros(closed.size, bool)
    normal[0::3] = closed[0::3]
    return normal, closed


def _held_response(rc, c, held: np.ndarray) -> float:
    """First-harmonic observed amplitude (m) at ``c.omega`` with the relative DOFs ``held`` at 0
    and the others force-free; inf where that system is singular."""
    from workflow.engine.condense import recover

    free = ~held
    z = np.zeros((2, held.size), complex)
    with np.errstate(all="ignore"):
        z[1, free] = _solve_or_inf(c.Zr[1][np.ix_(free, free)], c.Fr[1, free])
        return float(np.linalg.norm(recover(rc, c.omega, z)[1])) if np.all(np.isfinite(z)) else np.inf


def linear_frfs(rc, cond: list, static) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-harmonic observed amplitude (m) with the interface tied, sliding and stuck.

    Tied: u_r = 0 at every pair, separated ones too. Sliding (μ = 0): pairs in contact in the
    static state keep u_N = 0, tangential DOFs are free (λ_T = 0); separated pairs are free.
    Stuck: pairs in contact in the static state keep u_r = 0, separated ones are free — the
    friction-damped response's limit for μ → ∞ at small amplitude, where tied glues the
    separated pairs too. ``inf`` where the linear system is singular (an undamped resonance on
    a grid point).
    """
    from workflow.engine.condense import recover

    normal, closed = _held(static)
    tied, slide, stuck = [], [], []
    for c in cond:
        with np.errstate(all="ignore"):
            try:
                tied.append(np.linalg.norm(recover(rc, c.omega, np.zeros((2, rc.n_rel), complex))[1]))
            except np.linalg.LinAlgError:
                tied.append(np.inf)
        slide.append(_held_response(rc, c, normal))
        stuck.append(_held_response(rc, c, closed))
    return np.array(tied), np.array(slide), np.array(stuck)


def stuck_peak(rc, static, freqs_hz, stuck, xtol: float = 1e-6) -> dict | None:
    """The stuck response's resonance peak (:func:`linear_frfs`): its largest grid value refined
    between the two grid neighbours (bounded scalar search to ``xtol`` relative in frequency,
    one condensation at Nh = 1 a try) — {"hz", "amplitude_m", "grid_hz", "evaluations"} — or
    None where the largest value is at an end of the band (no peak in it) or not finite."""
    from scipy.optimize import minimize_scalar

    a = np.asarray(stuck, float)
    if a.size < 3 or not np.all(np.isfinite(a)):
        return None
    i = int(np.argmax(a))
    if i in (0, a.size - 1):
        return None
    closed = _held(static)[1]
    amp = lambda f: _held_response(rc, condensed(rc, 2 * np.pi * f, 1), closed)  # noqa: E731
    lo, hi = float(freqs_hz[i - 1]), float(freqs_hz[i + 1])
    res = minimize_scalar(lambda f: -amp(f), bounds=(lo, hi), method="bounded",
                          options={"xatol": xtol * float(freqs_hz[i])})
    hz, am = (float(res.x), float(-res.fun)) if -res.fun >= a[i] else (float(freqs_hz[i]), float(a[i]))
    return {"hz": hz, "amplitude_m": am, "grid_hz": float(freqs_hz[i]), "evaluations": int(res.nfev)}
