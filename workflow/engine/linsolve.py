"""Structured linear solves for the harmonic-balance Newton step (issue #16).

The HB Jacobian (:mod:`workflow.engine.hb`) is ``J = Rlin + G (diag ε − A)``. Brought
to harmonic coefficients (``J = L_r K L_p⁻¹``: L = I for HBM, the collocation
matrix on the left for TCM, T⁻¹ ⊗ I on both sides for HDHB) every method
shares one operator::

    K = Zb + G̃ (E − Zb)        (n × n, n = (2Nh+1)·3p, N/m)

* ``Zb`` — the condensed dynamic stiffness, block-diagonal over harmonics
  and dense over the 3p contact DOFs (eq. 4): applied harmonic by harmonic
  as complex products ``Z_j U_j``, O(Nh·(3p)²) per product;
* ``G̃`` — the DLFT derivative, block-diagonal over pairs and dense over the
  (2Nh+1)·3 coefficients of one pair (eqs. 13–17): O(p·(3nc)²);
* ``E`` — the penalties ε per contact DOF.

Neither factor is (n × n): K is applied matrix-free and solved by flexible
GMRES (PETSc's FGMRES, Saad 1993), right-preconditioned by the
harmonic-diagonal blocks of K, ``K_hh = Zb_hh + G̃_hh (E − Zb_hh)`` (one complex
LU of size 3p per harmonic, with the complex-linear part of G̃_hh:
:meth:`ContactJacobian.complex_harmonic_blocks`; exact real blocks below
:data:`INVERSE_MAX_DOFS`) combined, multiplicatively (cluster,
harmonic, cluster), with the exact *cluster*-diagonal blocks ``K_CC`` (all
harmonics of a few neighbouring pairs, :func:`pair_clusters`; blocks of about
:data:`CLUSTER_DOFS` unknowns). Why both: a stuck pair's rows are ≈ ε
(``G̃ ≈ I``) and a separated pair's are ``Zb`` (``G̃ = 0``) — neither couples
harmonics, the harmonic blocks hold them exactly; a slipping pair couples its
harmonics through ``G̃ E``, terms of size ε that only the pair blocks hold.
Measured on the quick sector (64 pairs, HBM Nh = 7, nit = 64, ε = 10³× the
stiffness, four Newton systems at resonance), GMRES iterations to 10⁻¹⁰:
harmonic blocks alone 166–200 (three stalled at 10⁻⁴…10⁻⁶), pair blocks alone
62–73, pair-then-harmonic 22–28, pair-harmonic-pair 13–18. What one pair's
block misses is the coupling of a slipping pair's harmonics to its neighbours'
through Zb (``G̃_p(h, h') Zb_h'[p, q]``); a cluster of neighbours holds it.

Newton asks for each step only the accuracy it needs (Eisenstat–Walker forcing
terms, :func:`workflow.engine.solvers.forcing`): 10⁻² while ‖R‖ is far from the
tolerance, tighter as it falls. Measured on the interface-scaling sectors (HBM
Nh = 7, nit = 64, 9 points, `python -m workflow.bench.structured_split`, one run
each, alone), GMRES iterations and seconds a sweep, every step to 10⁻¹⁰ → forcing
terms: 64 pairs 1193 → 458, 1.47 → 1.22 s; 128 pairs 1583 → 499, 7.7 → 4.8 s;
256 pairs 1152 → 451, 15.9 → 10.9 s; 512 pairs 2616 → 928, 102.0 → 56.9 s; the
Newton iterations 104 → 106 at 512 pairs, the peaks equal to 3e-9.

The preconditioner is *lagged*: kept across Newton steps (and ε-path steps
and chord-free trial points) until the GMRES iterations it has cost beyond
:data:`REFRESH_ITERS` a solve add up to one factorisation
(:meth:`StructuredSolve._account`), refactored from the current K then. GMRES always solves with
the current K, so every step is an (inexact) Newton step, never a chord step.
Memory: the harmonic blocks, (Nh+1)·(3p)² complex numbers, and the cluster blocks, three
arrays of (p/s)·(3·s·nc)² (50 MB at 512 pairs) — nothing of size n².

The harmonic LUs are complex (2026-11-28, ba339dd): a slipping pair's (cos, sin) block of G̃_hh
does not commute with the rotation of (cos, sin), so the exact K_hh is a real (6p)² matrix,
but its anti-linear part is the slipping pairs' alone, which the cluster blocks hold
exactly. Measured on the interface-scaling sectors (9 points, alone, against the exact real
blocks formed in float32): 512 pairs HBM factorisations 6.5 → 1.9 s, GMRES 19.9 → 17.2 s
(594 → 585 iterations), the sweep 37.0 → 31.4 s; HDHB 38.7 → 33.8 s (669 → 692 iterations);
256 pairs HBM 8.0 → 7.7 s, HDHB 7.0 → 6.6 s; the peaks equal to 4e-10.

The preconditioner runs in *single precision* (:data:`SINGLE`): its LUs, cluster
inverses and its own copy of Zr (complex64) and G̃. The solve is memory-bound
(every GMRES iteration reads Zr three times and the block LUs once), so halving
the bytes halves most of its time, and the LU factorisations are 2× faster.
A single-precision map is not linear to 1e-7, which plain GMRES cannot absorb
(measured with scipy's GMRES on 2026-11-27: it reported 1e-10 while the true
linear residual was 2e-5…9e-4); FGMRES keeps each preconditioned direction and
minimises the true residual, so the Newton step is the double-precision one to
:data:`GMRES_RTOL`. Measured on the interface-scaling sectors (HBM Nh = 7,
nit = 64, 9 points, one BLAS thread, alone, the same GMRES iteration counts and
peaks to 1e-15): 128 pairs 20.7 → 17.0 s (GMRES 16.2 → 12.0 s), 256 pairs
50.5 → 34.5 s (GMRES 41.2 → 24.5 s, factorisations 4.7 → 2.8 s), 512 pairs
531 → 289 s (GMRES 367 → 201 s, factorisations 121 → 45 s); results/reference/
interface-scaling/NOTES.md, "2026-11-27 (985ee51)".

*Small interfaces* (:data:`INVERSE_MAX_DOFS`) are bound by Python calls, not by bytes:
there the harmonic blocks are inverted explicitly (one batched product instead of Nh+1
triangular solves), Zr is held as real harmonic blocks (one batched product, no complex
conversions, :func:`real_blocks`), and the pair inverses are renewed only for the pairs
whose G̃ block changed since the last Newton step at that frequency (a stuck or separated
pair's block stays put).
"""
from __future__ import annotations


import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from workflow.engine import fourier
from workflow.engine.blas import large_blas

__all__ = ["ContactJacobian", "StructuredSolve", "k_apply", "zb_apply"]

#: The preconditioner's precision by default (:class:`StructuredSolve`): single.
SINGLE = True
#: Up to this many contact DOFs (3p) the harmonic blocks are inverted explicitly and applied as
#: one batched product instead of Nh+1 triangular solves, and Zr is held as real harmonic
#: blocks (:func:`real_blocks`): at these sizes the solves are Python-call bound, not
#: flop-bound. Measured (one BLAS thread, alone, sweeps of 50 points on paper-frf's 16 pairs,
#: 9 points on the interface-scaling sectors): 16 pairs HBM-17 nit=35 4.5–4.8 → 3.3 s (with
#: the pair inverses renewed only where G̃ changed: 3.0 s); 64 pairs HBM-7 3.4–3.5 → 3.5–4.0 s,
#: HDHB-7 2.5–3.0 → 2.6–2.9 s (a wash: the inverses cost what the solves save); 128 pairs
#: HBM-7 13.8–15.1 → 18.2–18.3 s (the factorisation 1.0 → 4.5 s).
INVERSE_MAX_DOFS = 96

#: Unknowns per cluster block of the preconditioner (3·pairs·(2Nh+1)): neighbouring pairs
#: share a block (:func:`pair_clusters`), which holds the coupling of their harmonics through
#: Zb that single-pair blocks miss. Measured on 22 Newton systems captured at 128 pairs (HDHB
#: Nh = 7, fresh blocks, GMRES to 1e-10): 762 iterations with one pair per block, 631 / 459 /
#: 258 / 234 with 2 / 4 / 8 / 16 pairs (HBM: 421 → 182 at 8). The blocks are inverted at every
#: Newton step and applied twice per GMRES iteration, so fewer iterations cost more per step;
#: whole sweeps (interface-scaling sectors, 9 points, one BLAS thread, alone, pairs = 1 →
#: 4 per cluster, i.e. 180 unknowns): 512 pairs HBM 277.7 → 202.7 s (8 per cluster: 240.0 s),
#: 256 pairs HBM 35.5–37.2 → 34.4–36.3 s and HDHB 63.1–65.1 → 53.0–56.8 s, 128 pairs HBM
#: 14.4–19.7 → 16.2–19.5 s and HDHB 23.8–27.5 → 18.7–21.2 s; 64 pairs HBM 3.3 → 4.4 s.
CLUSTER_DOFS = 180
#: From this many contact DOFs (3p) up the preconditioner's blocks are clusters of pairs
#: (:data:`CLUSTER_DOFS`), below single pairs: at 64 pairs the blocks cost more than the
#: GMRES iterations they save (above).
CLUSTER_MIN_DOFS = 384

#: GMRES tolerance relative to ‖rhs‖ of a tight solve: the default of :meth:`StructuredSolve.solve`
#: and the floor of the looser tolerances Newton passes it (:func:`workflow.engine.solvers.forcing`;
#: the nonlinear residual decides convergence).
GMRES_RTOL = 1e-10
#: GMRES iterations per Newton step (one cycle, no restart: restarted GMRES
#: stagnates where slipping pairs couple the harmonics strongly).
GMRES_RESTART = 100
#: relative linear residual above which lagged blocks are refactored and the
#: step repeated (and, with fresh blocks, counted in ``stats["failures"]``).
STALE_RESIDUAL = 1e-4
#: LSQR iterations of a Levenberg–Marquardt fallback step (:meth:`StructuredSolve.lm_step`):
#: the Golub–Kahan steps are most of a search's cost (2 products of J each), and the step only
#: has to get the iterate off a kink. Measured (interface-scaling sectors, Nh = 7, 9 points,
#: one BLAS thread, the same peaks to 1e-16): HDHB 256 pairs 30 → 8 steps 49.4 → 45.4 s (the
#: searches 6.4 → 3.1 s, 20 → 24 of them), 128 pairs 19.6 → 15.1 s (87 → 78 Newton
#: iterations); HBM 128 and 256 pairs and paper-frf's 16 pairs unchanged (0–1 searches).
LM_ITERS = 8
#: GMRES iterations per solve to :data:`GMRES_RTOL` that fresh blocks give on easy points
#: (a proportional share for a looser solve: GMRES's residual falls about geometrically); the
#: iterations beyond it are what lagged blocks cost (:meth:`StructuredSolve._account`).
REFRESH_ITERS = 25
#: one factorisation of the harmonic blocks costs about as many GMRES iterations as
#: ``FACTOR_ITERS[1]·(3p / FACTOR_ITERS[0])^FACTOR_ITERS[2]`` (3p contact DOFs). Measured with
#: the complex blocks (sweeps of the interface-scaling sectors, HBM Nh = 7, alone): 0.020 s a
#: factorisation against 4.8 ms a GMRES iteration at 128 pairs (4), 0.11 s against 9.9 ms at
#: 256 (11), 0.66 s against 29.7 ms at 512 (22). With the constants of the real (6p)² blocks,
#: (384, 16, 1.4) — 16 and 112 iterations at 128 and 512 pairs — the cheaper blocks were renewed
#: too seldom: 512 pairs HBM 32.1 → 29.4 s a sweep (GMRES 585 → 444 iterations, 3 → 5
#: factorisations), HDHB 34.6 → 27.2 s; 256 pairs HBM 7.0 → 6.5 s, HDHB 6.1 → 6.3 s; 128 pairs
#: unchanged (3.3 s, 3.0–3.1 s); the same peaks to 1e-9.
FACTOR_ITERS = (384.0, 6.0, 0.93)


def drop_negligible(B, dtype):
    """B (…, m, n) with the entries below ε(dtype)²·√(rᵢ cⱼ) set to zero in place (rᵢ, cⱼ
    the largest magnitude in row i and column j of each matrix): they cannot change a
    factorisation or a product carried in ``dtype``, and their products are subnormal
    numbers that the BLAS kernels process ~100× slower. The whole-disk blocks carry
    round-off of ~1e-30 relative from the FFT of the disk's circulant interface; measured
    on the 752-pair disk (2256², two cores) a complex64 LU took 60 s with them and 0.8 s
    without, the solve unchanged to 1e-7; its float32 cluster inverses (94 of 168²) took
    63 ms a product with them, ~1 ms without."""
    a = np.abs(B)
    tol = np.finfo(np.dtype(dtype)).eps ** 2
    B[a < tol * np.sqrt(a.max(axis=-1)[..., :, None] * a.max(axis=-2)[..., None, :])] = 0
    return B


def zb_apply(Zr, y, conj_transpose: bool = False):
    """``Zb y`` for real coefficients y (nc, nr[, k]) → same shape (N if y in m).

    ``Zr`` complex (Nh+1, nr, nr). Harmonic j acts as ``Z_j (y_jc − i y_js)``
    (eq. 4 in complex form); ``conj_transpose`` applies ``Zbᵀ`` (``Z_jᴴ``)."""
    U = fourier.real_to_complex(y)
    Z = np.conj(np.swapaxes(Zr, 1, 2)) if conj_transpose else Zr
    V = np.matmul(Z, U[..., None])[..., 0] if U.ndim == 2 else np.matmul(Z, U)
    V[0] = V[0].real
    return fourier.complex_to_real(V)


def split_pq(V, Y, compliance: bool):
    """(P Y, Q Y) from ``V = Zb Y`` (the harmonic products with the arrays of ``Zr``) for
    coefficients Y (nc, nr[, k]). The stiffness form has P = Zb, Q = I. The compliance form
    (``Zr`` holds Z_0 and the compliances H_j = Z_j⁻¹, j ≥ 1: unknowns the interface forces
    Z_j U_j of harmonics ≥ 1, the displacement of harmonic 0) has P = diag(Z_0, I, …) and
    Q = diag(I, H_1, …): the force the unknowns stand for is P Y, the displacement Q Y."""
    if not compliance:
        return V, Y
    P, Q = Y.copy(), V
    P[0] = V[0]
    Q[0] = Y[0]
    return P, Q


def k_apply(Zr, Gt, eps, Y, nc: int, p: int, compliance: bool = False):
    """``K Y = P Y + G̃ (E Q Y − P Y)`` for coefficients Y (nc, 3p, k) in the arrays' own
    precision (complex128/float64 for the Newton operator, complex64/float32 for the
    preconditioner's copies); P = Zb, Q = I in the stiffness form (:func:`split_pq`)."""
    Py, Qy = split_pq(zb_apply(Zr, Y), Y, compliance)
    return Py + _pair_apply(Gt, eps[:, None] * Qy - Py, nc, p)


def real_blocks(Zr, dtype=np.float64):
    """Zb as real harmonic blocks: (Z_0 (nr, nr), Z_h (Nh, 2nr, 2nr) with rows and columns
    (cos, sin) × DOF, ``[[Re Z_h, Im Z_h], [−Im Z_h, Re Z_h]]``) in ``dtype`` — the layout
    of the coefficient vector (2Nh+1, nr), so that harmonics 1…Nh are one batched product
    (:func:`zb_apply_blocks`). Twice the bytes of Zr: for small interfaces, where the
    conversions of :func:`zb_apply` cost more than the product."""
    return np.ascontiguousarray(Zr[0].real, dtype=dtype), fourier.real_block(Zr[1:], dtype)


def zb_apply_blocks(blocks, Y):
    """``Zb Y`` for coefficients Y (nc, nr, k) with Zb as :func:`real_blocks`."""
    Z0, Zh = blocks
    nc, nr, k = Y.shape
    out = np.empty_like(Y)
    out[0] = Z0 @ Y[0]
    out[1:] = np.matmul(Zh, Y[1:].reshape(nc // 2, 2 * nr, k)).reshape(nc - 1, nr, k)
    return out


def k_apply_blocks(blocks, Gt, eps, Y, nc: int, p: int, compliance: bool = False):
    """:func:`k_apply` with Zb as :func:`real_blocks`."""
    Py, Qy = split_pq(zb_apply_blocks(blocks, Y), Y, compliance)
    return Py + _pair_apply(Gt, eps[:, None] * Qy - Py, nc, p)


def _pair_apply(G, V, nc, p):
    """Block-diagonal-over-pairs G (p, 3nc, 3nc) times V (nc, 3p, k) → (nc, 3p, k)."""
    k = V.shape[-1]
    Vp = V.reshape(nc, p, 3, k).transpose(1, 0, 2, 3).reshape(p, 3 * nc, k)
    return np.matmul(G, Vp).reshape(p, nc, 3, k).transpose(1, 0, 2, 3).reshape(nc, 3 * p, k)


def cluster_size(nc: int, nr: int) -> int:
    """Pairs per preconditioner cluster for nc = 2Nh+1 coefficients and nr = 3p contact DOFs:
    blocks of about :data:`CLUSTER_DOFS` unknowns from :data:`CLUSTER_MIN_DOFS` contact DOFs
    up, one pair below."""
    return 1 if nr < CLUSTER_MIN_DOFS else max(1, CLUSTER_DOFS // (3 * nc))


def pair_clusters(Z0, size: int) -> list[np.ndarray]:
    """Groups of ``size`` strongly coupled contact pairs (the last may be smaller), sorted
    index arrays covering 0…p−1 once: the preconditioner's blocks (:class:`StructuredSolve`).

    Greedy aggregation on the normalised coupling of the static condensed stiffness
    ``Z0`` (nr, nr) (N/m): ``c_pq = ‖Z_pq‖_F / (‖Z_pp‖_F ‖Z_qq‖_F)^½``; a group is seeded on
    the rim of the pairs still free (the one least coupled to them) and grows by the free
    pair most coupled to the group so far, so the groups are compact patches of neighbours
    on a flank grid and no stranded pairs are left for a last, scattered one. Algebraic, as
    in aggregation multigrid: a bundle without meaningful pair positions clusters as well."""
    p = Z0.shape[0] // 3
    size = int(max(1, min(size, p)))
    if size == 1:
        return [np.array([q]) for q in range(p)]
    N = np.sqrt(np.sum(np.abs(np.asarray(Z0, float).reshape(p, 3, p, 3)) ** 2, axis=(1, 3)))
    d = np.sqrt(np.maximum(np.diag(N), 1e-300))
    C = N / d[:, None] / d[None, :]
    np.fill_diagonal(C, 0.0)
    free = np.ones(p, dtype=bool)
    out = []
    while free.any():
        rim = np.where(free, C @ free, np.inf)
        group = [int(np.argmin(rim))]
        free[group[0]] = False
        score = C[group[0]].copy()
        while len(group) < size and free.any():
            q = int(np.argmax(np.where(free, score, -1.0)))
            group.append(q)
            free[q] = False
            score += C[q]
        out.append(np.array(sorted(group)))
    return out


def cluster_groups(clusters: list[np.ndarray]) -> list[np.ndarray]:
    """The clusters of :func:`pair_clusters` stacked by size: index arrays (g, s), one per size,
    so that each size is one batched product."""
    sizes = sorted({len(c) for c in clusters}, reverse=True)
    return [np.stack([c for c in clusters if len(c) == s]) for s in sizes]


def _cluster_k(G, Zcc, M):
    """``K_CC = Zb_CC + G̃_C (E_C − Zb_CC)`` (g, m, m) from the clusters' pair blocks G̃
    (g, s, 3nc, 3nc) and :meth:`ContactJacobian.cluster_parts` (Zcc, M)."""
    g, s = G.shape[:2]
    m = Zcc.shape[1]
    return Zcc + np.matmul(G, M.reshape(g, s, m // s, m)).reshape(g, m, m)


def _cluster_apply(inv, groups, V, nc, p):
    """Block-diagonal-over-clusters ``inv`` (one (g, m, m) array per group of
    :func:`cluster_groups`, rows and columns (pair, coefficient, c)) times V (nc, 3p, k)."""
    if len(groups) == 1 and groups[0].shape[1] == 1:        # one pair per block, in order
        return _pair_apply(inv[0], V, nc, p)
    k = V.shape[-1]
    V4 = V.reshape(nc, p, 3, k)
    out = np.empty_like(V4)
    for B, idx in zip(inv, groups):
        g, s = idx.shape
        Vc = V4[:, idx].transpose(1, 2, 0, 3, 4).reshape(g, s * nc * 3, k)
        out[:, idx] = np.matmul(B, Vc).reshape(g, s, nc, 3, k).transpose(2, 0, 1, 3, 4)
    return out.reshape(nc, 3 * p, k)


def _harmonic_index(h):
    return [0] if h == 0 else [2 * h - 1, 2 * h]


def _bidiagonalise(op, b, steps: int):
    """Golub–Kahan bidiagonalisation ``op V = U B`` started from ``b``: (V (n, k),
    B (k+1, k) lower bidiagonal, β₁ = ‖b‖), k ≤ ``steps`` (fewer on breakdown).
    No reorthogonalisation, as in LSQR."""
    n = op.shape[1]
    V = np.zeros((n, steps))
    B = np.zeros((steps + 1, steps))
    beta1 = float(np.linalg.norm(b))
    if not beta1 > 0 or not np.isfinite(beta1):
        return V[:, :0], B[:1, :0], beta1
    u = b / beta1
    w = op.rmatvec(u)
    alpha = float(np.linalg.norm(w))
    k = 0
    while k < steps and alpha > 0 and np.isfinite(alpha):
        v = w / alpha
        V[:, k] = v
        B[k, k] = alpha
        u = op.matvec(v) - alpha * u
        beta = float(np.linalg.norm(u))
        B[k + 1, k] = beta
        k += 1
        if k == steps or not beta > 0 or not np.isfinite(beta):
            break
        u /= beta
        w = op.rmatvec(u) - beta * v
        alpha = float(np.linalg.norm(w))
    return V[:, :k], B[:k + 1, :k], beta1


def _bordered(k, pre, col, c, c_s: float):
    """(mult, preconditioner) of the bordered ``[[K, col], [cᵀ, c_s]]`` from K's product ``k`` and
    its preconditioner ``pre`` (≈ K⁻¹): the preconditioner is the exact inverse of the same
    bordering of ``pre``, ``[dz; ds]`` with ``y = pre(r_z)``, ``y_c = pre(col)`` (once a solve),
    ``ds = (r_s − c·y) / (c_s − c·y_c)``, ``dz = y − ds y_c`` — so GMRES on the bordered system
    takes about K's own iterations, one Krylov solve where solving K twice took two."""
    n = col.size
    y_c = pre(col)
    den = c_s - c @ y_c

    def mult(v):
        return np.append(k(v[:n]) + col * v[n], c @ v[:n] + c_s * v[n])

    def precond(r):
        y = pre(r[:n])
        ds = (r[n] - c @ y) / den if den != 0 else 0.0
        return np.append(y - ds * y_c, ds)
    return mult, precond


class _Apply:
    """A PETSc shell matrix's ``mult`` / shell preconditioner's ``apply``: y = f(x)."""

    def __init__(self, f):
        self.f = f

    def mult(self, mat, x, y):
        y.array[:] = self.f(x.array_r)

    def apply(self, pc, x, y):
        y.array[:] = self.f(x.array_r)


class ContactJacobian(scipy.sparse.linalg.LinearOperator):
    """``J = L_r K L_p⁻¹`` with ``K = Zb + G̃ (E − Zb)`` (module docstring), matrix-free.

    Zr (Nh+1, nr, nr) complex N/m; eps (nr,) N/m; Gt (p, 3nc, 3nc) the per-pair
    DLFT blocks in coefficient space (dimensionless); ``left`` (nc, nc) or None
    maps K's rows to J's (J = left·K·right); ``right`` (nc, nc) or None maps
    J's unknowns to coefficients. Never holds an (n × n) array. ``compliance``: Zr holds Z_0
    and the compliances H_j (m/N) of harmonics ≥ 1, whose unknowns are forces, and
    ``K = P + G̃ (E Q − P)`` (:func:`split_pq`): for those harmonics ``I + G̃ (E H − I)``,
    the stiffness form's K times H.
    """

    def __init__(self, Zr, eps, Gt, left=None, right=None, compliance: bool = False):
        self.Zr, self.eps, self.Gt = Zr, np.asarray(eps, float), Gt
        self.compliance = bool(compliance)
        self.nh = Zr.shape[0] - 1
        self.nc, self.nr = fourier.n_coef(self.nh), Zr.shape[1]
        self.p = self.nr // 3
        self.left, self.right = left, right
        self._ZrH = self._GtT = None        # Zᴴ and G̃ᵀ, for Jᵀ products (LM steps)
        self._left_inv = None if left is None else np.linalg.inv(left)
        self._right_inv = None if right is None else np.linalg.inv(right)
        n = self.nc * self.nr
        super().__init__(dtype=float, shape=(n, n))

    def finite(self) -> bool:
        return bool(np.all(np.isfinite(self.Gt)))

    def k_apply(self, Y):
        """K Y for coefficients Y (nc, nr, k)."""
        return k_apply(self.Zr, self.Gt, self.eps, Y, self.nc, self.p, self.compliance)

    def k_apply_t(self, Y):
        """Kᵀ Y = Pᵀ (Y − G̃ᵀ Y) + Qᵀ E G̃ᵀ Y (stiffness form: P = Zb, Q = I)."""
        if self._ZrH is None:
            self._ZrH = np.conj(np.swapaxes(self.Zr, 1, 2))
            self._GtT = np.ascontiguousarray(np.swapaxes(self.Gt, 1, 2))
        W = _pair_apply(self._GtT, Y, self.nc, self.p)
        if not self.compliance:
            return zb_apply(self._ZrH, Y - W) + self.eps[:, None] * W
        D, EW = Y - W, self.eps[:, None] * W
        PtD, _ = split_pq(zb_apply(self._ZrH, D), D, True)
        _, QtEW = split_pq(zb_apply(self._ZrH, EW), EW, True)
        return PtD + QtEW

    @staticmethod
    def _lmul(L, Y):
        return Y if L is None else np.einsum("ab,bnk->ank", L, Y)

    def _matmat(self, X):
        Y = X.reshape(self.nc, self.nr, -1)
        out = self._lmul(self.left, self.k_apply(self._lmul(self.right, Y)))
        return out.reshape(self.shape[0], -1)

    def _rmatmat(self, X):
        Y = X.reshape(self.nc, self.nr, -1)
        tr = None if self.left is None else self.left.T
        out = self._lmul(None if self.right is None else self.right.T, self.k_apply_t(self._lmul(tr, Y)))
        return out.reshape(self.shape[0], -1)

    def _matvec(self, x):
        return self._matmat(x[:, None])[:, 0]

    def _rmatvec(self, x):
        return self._rmatmat(x[:, None])[:, 0]

    def todense(self) -> np.ndarray:
        """The (n × n) J — for tests and small problems only."""
        return self._matmat(np.eye(self.shape[1]))

    def pair_blocks(self) -> np.ndarray:
        """The exact pair-diagonal blocks of K, (p, 3nc, 3nc), rows/columns (coefficient, c):
        ``K_pp = Zb_pp + G̃_p (E_p − Zb_pp)`` — every harmonic of one pair, the
        pair's own 3×3 stiffness only (:meth:`cluster_blocks` with one pair a cluster)."""
        return self.cluster_blocks(np.arange(self.p)[:, None])

    def cluster_parts(self, idx: np.ndarray):
        """(Zb_CC, E_C − Zb_CC), each (g, m, m) with m = 3·s·nc, for the clusters ``idx``
        (g, s) of pairs (:func:`pair_clusters`), rows and columns (pair, coefficient, c): the
        frequency- and ε-only parts of the cluster-diagonal blocks of K,
        ``K_CC = Zb_CC + G̃_C (E_C − Zb_CC)`` with G̃_C block-diagonal over the cluster's pairs."""
        nc, nh = self.nc, self.nh
        g, s = idx.shape
        dofs = (3 * idx[:, :, None] + np.arange(3)).reshape(g, 3 * s)
        Z5 = self.Zr[:, dofs[:, :, None], dofs[:, None, :]].reshape(nh + 1, g, s, 3, s, 3)
        Zcc = np.zeros((g, s, nc, 3, s, nc, 3))
        Zcc[:, :, 0, :, :, 0, :] = Z5[0].real
        # harmonic j's (cos, sin) rows and columns 2j−1, 2j: its real form, (g, a, q, c, b, q', c')
        blocks = fourier.real_block(Z5[1:].reshape(nh, g, 3 * s, 3 * s)).reshape(nh, g, 2, s, 3, 2, s, 3)
        for j in range(1, nh + 1):
            Zcc[:, :, 2 * j - 1:2 * j + 1, :, :, 2 * j - 1:2 * j + 1, :] = blocks[j - 1].transpose(0, 2, 1, 3, 5, 4, 6)
        m = 3 * s * nc
        Zcc = Zcc.reshape(g, m, m)
        E = np.broadcast_to(self.eps[dofs].reshape(g, s, 1, 3), (g, s, nc, 3)).reshape(g, m)
        if self.compliance:     # P_CC, E Q_CC − P_CC: harmonic 0's block is Z_0's, the others' H's
            h0 = np.tile(np.repeat(np.arange(nc) == 0, 3), s)
            Q = np.where(~h0[:, None] & ~h0[None, :], Zcc, 0.0)
            Q[:, h0, h0] = 1.0
            P = np.where(h0[:, None] & h0[None, :], Zcc, 0.0)
            P[:, ~h0, ~h0] = 1.0
            return P, E[:, :, None] * Q - P
        M = -Zcc
        M[:, np.arange(m), np.arange(m)] += E
        return Zcc, M

    def cluster_blocks(self, idx: np.ndarray) -> np.ndarray:
        """The exact cluster-diagonal blocks of K (g, m, m) for the clusters ``idx`` (g, s),
        rows and columns (pair, coefficient, c) (:meth:`cluster_parts`)."""
        return _cluster_k(self.Gt[idx], *self.cluster_parts(idx))

    def complex_harmonic_blocks(self, dtype=np.float64):
        """Yields (idx, B_h), the preconditioner's harmonic blocks for its LUs: harmonic 0's
        exact real block K_00 (:meth:`harmonic_blocks`), then per harmonic h ≥ 1 the complex
        (nr × nr) ``B_h = (I − Ĝ_h) Z_h + Ĝ_h E`` in the precision of ``dtype`` (complex64 for
        float32), Ĝ_h the complex-linear part of each pair's (cos, sin) block of G̃_hh:
        ``ĝ = (g_cc + g_ss)/2 + i (g_cs − g_sc)/2`` for ``U = u_c − i u_s``. That is K_hh
        exactly where G̃_hh commutes with the rotation of (cos, sin) — stuck (G̃ ≈ I) and
        separated (G̃ = 0) pairs, most of an interface; a slipping pair's anti-linear part
        (its coupling of U_h to conj(U_h)) is left to the cluster blocks, which hold every
        harmonic of a pair exactly. Half the bytes and a quarter of the flops of the real
        (2nr)² block: measured at 512 pairs (HBM Nh = 7, 9 points, alone) the factorisations
        6.5 → 1.9 s a sweep and GMRES 19.9 → 17.2 s for 594 → 585 iterations (module docstring)."""
        nc, nr, p = self.nc, self.nr, self.p
        G5 = self.Gt.reshape(p, nc, 3, nc, 3)
        ip = np.arange(p)
        cdt = np.result_type(dtype, np.complex64)
        for h in range(self.nh + 1):
            idx = _harmonic_index(h)
            if h == 0:
                Zh, Gp, t = self.Zr[0].real, G5[:, 0, :, 0, :], dtype
            else:
                c, s = idx
                Zh, t = self.Zr[h], cdt
                Gp = 0.5 * (G5[:, c, :, c, :] + G5[:, s, :, s, :]) + 0.5j * (G5[:, c, :, s, :] - G5[:, s, :, c, :])
            if self.compliance and h > 0:   # (I − Ĝ) + Ĝ E H_h
                B = np.matmul(Gp.astype(t), (self.eps[:, None] * Zh).astype(t).reshape(p, 3, nr))
                for d in range(3):
                    B[ip, :, 3 * ip + d] += (np.eye(3)[:, d] - Gp[:, :, d]).astype(t)
                yield idx, drop_negligible(B.reshape(nr, nr), dtype)
                continue
            B = np.matmul((np.eye(3) - Gp).astype(t), Zh.astype(t).reshape(p, 3, nr))
            for d in range(3):
                B[ip, :, 3 * ip + d] += Gp[:, :, d] * self.eps[3 * ip + d, None]
            yield idx, drop_negligible(B.reshape(nr, nr), dtype)

    def harmonic_blocks(self, dtype=np.float64):
        """Yields (idx, K_hh), the exact harmonic-diagonal blocks of K, (s·nr)² each, formed in
        ``dtype`` pair by pair as ``K_hh = (I − G̃_hh) Zb_hh + G̃_hh E`` (E touches only the
        pair's own columns): the small interfaces' explicit inverses
        (:meth:`StructuredSolve._invert_blocks`); the LUs of larger ones take
        :meth:`complex_harmonic_blocks`."""
        nc, nr, p = self.nc, self.nr, self.p
        G5 = self.Gt.reshape(p, nc, 3, nc, 3)
        ip = np.arange(p)
        for h in range(self.nh + 1):
            idx = _harmonic_index(h)
            s = len(idx)
            Z = self.Zr[h]
            Zh = Z.real.astype(dtype) if s == 1 else fourier.real_block(Z, dtype)
            Gh = G5[:, idx][:, :, :, idx].reshape(p, 3 * s, 3 * s)
            if self.compliance and h > 0:   # (I − G̃_hh) + G̃_hh E H_hh
                EH = (np.tile(self.eps, s)[:, None] * Zh).astype(dtype)
                rows = EH.reshape(s, p, 3, s * nr).transpose(1, 0, 2, 3).reshape(p, 3 * s, s * nr)
                K = np.matmul(Gh.astype(dtype), rows).reshape(p, 3 * s, s, nr)
                I_G = np.eye(3 * s) - Gh
                for a in range(s):
                    for c in range(3):
                        K[ip, :, a, 3 * ip + c] += I_G[:, :, 3 * a + c]
                yield idx, K.reshape(p, s, 3, s * nr).transpose(1, 0, 2, 3).reshape(s * nr, s * nr)
                continue
            # rows (s, p, 3) → per pair (p, 3s) to meet G̃_hh (p, 3s, 3s)
            rows = Zh.reshape(s, p, 3, s * nr).transpose(1, 0, 2, 3).reshape(p, 3 * s, s * nr)
            K = np.matmul((np.eye(3 * s) - Gh).astype(dtype), rows).reshape(p, 3 * s, s, nr)
            for a in range(s):
                for c in range(3):
                    K[ip, :, a, 3 * ip + c] += Gh[:, :, 3 * a + c] * self.eps[3 * ip + c, None]
            yield idx, K.reshape(p, s, 3, s * nr).transpose(1, 0, 2, 3).reshape(s * nr, s * nr)


class StructuredSolve:
    """The Newton linear solver on a :class:`ContactJacobian`: flexible GMRES with the
    lagged cluster–harmonic–cluster preconditioner (module docstring). Same protocol as
    :class:`workflow.engine.solvers.DenseLU` (``factor``, ``solve``, ``lm_step``).

    ``single``: the preconditioner in single precision (:data:`SINGLE`); a solve
    that fresh single-precision blocks cannot bring below :data:`STALE_RESIDUAL`
    switches this solver to double precision for good. ``stats``: factorizations,
    GMRES iterations, solves, failures, ``precision`` ("single" or "double").
    Under MPI, PETSc must be initialised on every rank before a rank's first solve
    (its KSP lives on COMM_SELF, but importing petsc4py is collective):
    :func:`workflow.engine.frf` with ``comm`` and the CLI do it."""

    name = "structured"

    def __init__(self, single: bool = SINGLE):
        self.op: ContactJacobian | None = None
        self._lu = None
        self._inv = None            # explicit harmonic-block inverses (small interfaces)
        self._pp = None             # cluster blocks at one frequency and ε (:meth:`_cluster_inverses`)
        self._groups = None         # ((p, nc), cluster_groups(...)): the preconditioner's pair clusters
        self._lu_op = None
        self._refresh = True
        self._excess = 0.0          # GMRES iterations beyond REFRESH_ITERS since the last factorisation
        self._gk = None             # (operator, R, V, B, β₁) of the last LM bidiagonalisation
        self._real = np.float32 if single else np.float64
        # (Zr, its copy in the preconditioner's precision, its real blocks in double or None):
        # real blocks (real_blocks) up to INVERSE_MAX_DOFS, complex above
        self._zr_pre = (None, None, None)
        self._compliance = False    # the operator's form, for the preconditioner's own products
        self.stats = {"factorizations": 0, "gmres_iterations": 0, "solves": 0, "failures": 0,
                      "precision": "single" if single else "double"}

    reusable = True

    def _blas(self, op):
        """BLAS threads of this solver's work on ``op`` (:func:`large_blas`)."""
        return large_blas(op.nr)

    def factor(self, op) -> bool:
        """Take a fresh operator; the preconditioner is kept unless stale."""
        with self._blas(op):
            return self._factor(op)

    #: :func:`workflow.engine.solvers.newton` may pass a linear tolerance (an inexact Newton step)
    inexact = True

    def solve(self, R, rtol: float | None = None, border=None):
        """The Newton step dx of ``J dx = −R`` (None if nothing finite came out) to the relative
        linear residual ``rtol`` (:data:`GMRES_RTOL` if None or below it): :meth:`_solve`.
        ``border`` (col (n,), c (n,), c_s): the bordered ``[[J, col], [cᵀ, c_s]]`` instead (one
        more unknown and equation: a held amplitude's load scale), R and the step of size n + 1."""
        with self._blas(self.op):
            return self._solve(R, GMRES_RTOL if rtol is None else max(rtol, GMRES_RTOL), border)

    def lm_step(self, R, nu):
        """Levenberg–Marquardt step: :meth:`_lm_step`."""
        with self._blas(self.op):
            return self._lm_step(R, nu)

    def _factor(self, op) -> bool:
        if not op.finite():
            return False
        self.op = op
        real = self._real
        with np.errstate(over="ignore", invalid="ignore"):  # out of float32: caught by solve(), double then
            if self._zr_pre[0] is not op.Zr:    # Zr is one array per frequency: copied once, not per step
                self._zr_pre = (op.Zr, real_blocks(op.Zr, real) if op.nr <= INVERSE_MAX_DOFS else
                                self._precision_copy(op.Zr),
                                real_blocks(op.Zr) if op.nr <= INVERSE_MAX_DOFS else None)
            self._pre = (self._zr_pre[1], op.Gt.astype(real, copy=False), op.eps.astype(real))
            self._compliance = op.compliance
            self._cluster_inverses(op)
        if self._lu is None or self._refresh or self._lu[0] != (op.nc, op.nr):
            self._factor_blocks(op)
        return True

    def _precision_copy(self, Zr):
        """Zr in the preconditioner's precision: Zr itself in double, else written into the
        previous frequency's copy where it fits — a fresh 151 MB array at every frequency (512
        pairs, Nh = 7) cost its page faults as well: measured 0.75 → 0.11 s of casts a sweep."""
        dt = np.result_type(self._real, np.complex64)
        if Zr.dtype == dt:
            return Zr
        old = self._zr_pre[1]
        if isinstance(old, np.ndarray) and old.shape == Zr.shape and old.dtype == dt and old is not Zr:
            np.copyto(old, Zr, casting="same_kind")
            return old
        return Zr.astype(dt)

    def _cluster_inverses(self, op):
        """The inverses of K's cluster-diagonal blocks (:meth:`ContactJacobian.cluster_parts`,
        clusters of :func:`pair_clusters`) in the preconditioner's precision, fresh at every
        Newton step but only for the clusters with a pair whose G̃ block changed since the
        last step at this frequency and ε: a stuck or separated pair's block stays put while
        Newton converges (measured on paper-frf's HBM-17: the pair inverses were a third of
        the structured solve's time)."""
        real = self._real
        if self._groups is None or self._groups[0] != (op.p, op.nc):
            self._groups = ((op.p, op.nc), cluster_groups(pair_clusters(op.Zr[0].real, cluster_size(op.nc, op.nr))))
        groups = self._groups[1]
        pp = self._pp
        if pp is None or pp["Zr"] is not op.Zr or not np.array_equal(pp["eps"], op.eps) \
                or pp["groups"] is not groups or pp["inv"][0].dtype != real:
            # in the preconditioner's precision: the blocks are formed and inverted there anyway
            parts = [tuple(a.astype(real) for a in op.cluster_parts(idx)) for idx in groups]
            pp = self._pp = {"Zr": op.Zr, "eps": op.eps.copy(), "groups": groups, "parts": parts, "Gt": None,
                             "inv": [np.empty(Z.shape, dtype=real) for Z, _ in parts]}
        changed = np.ones(op.p, dtype=bool) if pp["Gt"] is None else np.any(pp["Gt"] != op.Gt, axis=(1, 2))
        for (Zcc, M), inv, idx in zip(pp["parts"], pp["inv"], groups):
            todo = np.flatnonzero(np.any(changed[idx], axis=1))
            if not len(todo):
                continue
            K = _cluster_k(op.Gt[idx[todo]].astype(real, copy=False), Zcc[todo], M[todo])
            try:
                with np.errstate(over="ignore"):
                    inv[todo] = drop_negligible(np.linalg.inv(K.astype(real, copy=False)), real)
            except np.linalg.LinAlgError:
                inv[todo] = np.linalg.pinv(K)
        if pp["Gt"] is None:
            pp["Gt"] = op.Gt.copy()
        else:
            pp["Gt"][changed] = op.Gt[changed]
        self._cluster_inv = pp["inv"]

    def _factor_blocks(self, op):
        self._inv = self._invert_blocks(op) if op.nr <= INVERSE_MAX_DOFS else None
        lus = []
        with np.errstate(over="ignore", invalid="ignore"):  # out of float32: caught by solve(), double then
            for idx, K in (() if self._inv is not None else op.complex_harmonic_blocks(self._real)):
                try:
                    lus.append((idx, scipy.linalg.lu_factor(K, overwrite_a=True, check_finite=False)))
                except (ValueError, np.linalg.LinAlgError):
                    lus.append((idx, None))
        self._lu = ((op.nc, op.nr), lus)
        self._lu_op = op
        self._refresh = False
        self._excess = 0.0
        self.stats["factorizations"] += 1

    def _invert_blocks(self, op):
        """(K_00⁻¹, stacked K_hh⁻¹ (Nh, 2nr, 2nr)) in the preconditioner's precision, or None
        if a block is singular (the LUs then, which pass a singular block's rows through)."""
        try:
            with np.errstate(all="ignore"):
                blocks = [K for _, K in op.harmonic_blocks(self._real)]
                inv0 = np.linalg.inv(blocks[0].astype(self._real, copy=False))
                invh = np.linalg.inv(np.stack(blocks[1:]).astype(self._real, copy=False)) if op.nh else None
        except np.linalg.LinAlgError:
            return None
        return inv0, invh

    def _harmonic_solve(self, x):
        nc, nr = self._lu[0]
        Y = x.reshape(nc, nr)
        out = np.empty_like(Y)
        if self._inv is not None:
            inv0, invh = self._inv
            out[0] = inv0 @ Y[0]
            if invh is not None:
                out[1:] = np.matmul(invh, Y[1:].reshape(nc // 2, 2 * nr, 1)).reshape(nc - 1, nr)
            return out.ravel()
        for idx, lu in self._lu[1]:     # complex blocks for h ≥ 1 (:meth:`ContactJacobian.complex_harmonic_blocks`)
            if lu is None:
                out[idx] = Y[idx]
            elif len(idx) == 1:
                out[idx[0]] = scipy.linalg.lu_solve(lu, Y[idx[0]], check_finite=False)
            else:
                X = scipy.linalg.lu_solve(lu, Y[idx[0]] - 1j * Y[idx[1]], check_finite=False)
                out[idx[0]], out[idx[1]] = X.real, -X.imag
        return out.ravel()

    def _cluster_solve(self, x):
        op = self.op
        return _cluster_apply(self._cluster_inv, self._groups[1], x.reshape(op.nc, op.nr, 1), op.nc, op.p).ravel()

    def _k(self, x):
        op = self.op
        Y = x.reshape(op.nc, op.nr, 1)
        if self._zr_pre[2] is not None and self._zr_pre[0] is op.Zr:
            return k_apply_blocks(self._zr_pre[2], op.Gt, op.eps, Y, op.nc, op.p, op.compliance).ravel()
        return op.k_apply(Y).ravel()

    def _k_pre(self, x):
        """K x in the preconditioner's precision (its own copies of Zr, G̃, ε)."""
        op = self.op
        apply = k_apply_blocks if self._zr_pre[2] is not None else k_apply
        return apply(*self._pre, x.reshape(op.nc, op.nr, 1), op.nc, op.p, self._compliance).ravel()

    def _precond(self, r):
        """Symmetric multiplicative Schwarz: cluster blocks, harmonic blocks, cluster blocks (in the
        preconditioner's precision; the result in double)."""
        r = r.astype(self._real, copy=False)
        with np.errstate(all="ignore"):     # a non-finite result is caught by solve(): double precision then
            z = self._cluster_solve(r)
            z = z + self._harmonic_solve(r - self._k_pre(z))
            return (z + self._cluster_solve(r - self._k_pre(z))).astype(float, copy=False)

    def _k_solve(self, b, rtol: float = GMRES_RTOL, border=None):
        """Solve K z = b (coefficient space) to ``rtol`` by right-preconditioned flexible GMRES
        (PETSc's FGMRES: the preconditioned directions are kept, so a preconditioner that is
        not an exact linear map — single precision — still gives the true residual):
        (z, relative residual ‖Kz − b‖/‖b‖, iterations). ``border`` (col, c, c_s): the bordered
        system ``[[K, col], [cᵀ, c_s]]`` of size n + 1 instead, preconditioned by the same
        bordering of the preconditioner (:func:`_bordered`)."""
        from petsc4py import PETSc

        k, pre = (self._k, self._precond) if border is None else _bordered(self._k, self._precond, *border)
        n = self.op.shape[0] + (border is not None)
        contexts = (_Apply(k), _Apply(pre))
        A = PETSc.Mat().createPython([n, n], contexts[0], comm=PETSc.COMM_SELF)
        ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        pc = ksp.getPC()
        x, rhs = PETSc.Vec().createSeq(n, comm=PETSc.COMM_SELF), PETSc.Vec().createSeq(n, comm=PETSc.COMM_SELF)
        try:
            A.setUp()
            ksp.setType(PETSc.KSP.Type.FGMRES)
            ksp.setOperators(A)
            ksp.setGMRESRestart(GMRES_RESTART)
            ksp.setTolerances(rtol=rtol, atol=0.0, divtol=1e300, max_it=GMRES_RESTART)
            pc.setType(PETSc.PC.Type.PYTHON)
            pc.setPythonContext(contexts[1])
            ksp.setPCSide(PETSc.PC.Side.RIGHT)
            ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
            rhs.array[:] = b
            ksp.solve(rhs, x)
            its = int(ksp.getIterationNumber())
            bn = float(np.linalg.norm(b))
            res = float(ksp.getResidualNorm())
            rel = 0.0 if bn == 0 else (res / bn if np.isfinite(res) else np.inf)
            z = x.array.copy()
        finally:
            # ksp.getPC() is a reference of its own: destroying the KSP alone left the PC and its
            # Python context alive, and with it this solver, its Z_r copy and its LU factors
            # (0.67 GB a point on the 47-blade disk). The contexts also let go of the solver, so
            # whatever PETSc keeps holds no arrays.
            for c in contexts:
                c.f = None
            for o in (ksp, pc, A, x, rhs):
                o.destroy()
        self.stats["gmres_iterations"] += its
        self.stats["solves"] += 1
        self._account(its, rtol)
        return z, rel, its

    def _account(self, its: int, rtol: float = GMRES_RTOL) -> None:
        """Lagged blocks are refactored once the GMRES iterations beyond
        :data:`REFRESH_ITERS` they have cost add up to one factorisation
        (:data:`FACTOR_ITERS`). Refactoring at the first solve over the
        threshold (the rule before) renewed the blocks at every Newton step of the
        strongly slipping points, where even fresh blocks need 35–60 iterations,
        while a factorisation costs 4 (128 pairs) to 22 (512 pairs) iterations."""
        self._excess += max(0.0, its - REFRESH_ITERS * np.log(rtol) / np.log(GMRES_RTOL))
        dofs, at, power = FACTOR_ITERS
        if self._excess >= at * (self._lu[0][1] / dofs) ** power:
            self._refresh = True

    def _solve(self, R, rtol: float, border=None):
        """The Newton step dx of ``J dx = −R`` (None if nothing finite came out).

        An inexact Newton step: GMRES stops at ``rtol`` or after
        :data:`GMRES_RESTART` iterations, whichever first; the nonlinear residual
        decides convergence. Blocks from an older J that leave more than
        :data:`STALE_RESIDUAL` (or ``rtol``, if looser) are refactored from
        the current J and the solve repeated once; single-precision blocks that
        still leave more are given up for double precision (the blocks of an
        extreme ε can be too ill-conditioned for float32) and the solve repeated."""
        op = self.op
        b = -np.asarray(R, float)
        n = op.shape[0]
        b_x = b[:n].reshape(op.nc, op.nr)
        if op._left_inv is not None:
            b_x = op._left_inv @ b_x
        b = np.concatenate([b_x.ravel(), b[n:]])
        kw = {} if border is None else {"border": self._coefficient_border(op, *border)}
        stale = max(STALE_RESIDUAL, rtol)
        z, rel, _ = self._k_solve(b, rtol, **kw)
        if rel > stale and self._lu_op is not op:
            self._factor_blocks(op)
            z, rel, _ = self._k_solve(b, rtol, **kw)
        if rel > stale and self._real is not np.float64:
            self._real = np.float64
            self.stats["precision"] = "double"
            self._lu, self._zr_pre = None, (None, None, None)
            self._factor(op)
            z, rel, _ = self._k_solve(b, rtol, **kw)
        if rel > stale:
            self.stats["failures"] += 1
        zx = z[:n].reshape(op.nc, op.nr)
        dx = np.concatenate([(zx if op._right_inv is None else op._right_inv @ zx).ravel(), z[n:]])
        return dx if np.all(np.isfinite(dx)) else None

    @staticmethod
    def _coefficient_border(op, col, c, c_s):
        """A border (col, c, c_s) of J in the coefficient space of K
        (``J = L_r K L_p⁻¹``: col → L_r⁻¹ col, c → L_p⁻ᵀ c)."""
        col = np.asarray(col, float).reshape(op.nc, op.nr)
        c = np.asarray(c, float).reshape(op.nc, op.nr)
        if op._left_inv is not None:
            col = op._left_inv @ col
        if op._right_inv is not None:
            c = op._right_inv.T @ c
        return col.ravel(), c.ravel(), float(c_s)

    def _lm_step(self, R, nu):
        """Levenberg–Marquardt step ``min ‖J dx + R‖² + ν‖dx‖²``, matrix-free and
        approximate: the damped least-squares solution on the Krylov space of
        :data:`LM_ITERS` Golub–Kahan bidiagonalisation steps of J from R — LSQR's
        iterate after as many steps (Paige & Saunders 1982, §§3–4). The step only
        has to get the iterate off a kink, and unpreconditioned LSQR on this badly
        scaled J would need thousands (measured: 200 a step were 85 % of a
        resonance point's time on 64 pairs). The bidiagonalisation does not depend
        on ν, so the growing dampings of one search (:func:`workflow.engine.solvers._lm_search`)
        share it: 2·LM_ITERS products of J for all of them instead of each."""
        R = np.asarray(R, float)
        if self._gk is None or self._gk[0] is not self.op or not np.array_equal(self._gk[1], R):
            self._gk = (self.op, R.copy(), *_bidiagonalise(self.op, -R, LM_ITERS))
        _, _, V, B, beta1 = self._gk
        k = B.shape[1]
        if k == 0:
            return np.zeros_like(R)
        A = np.vstack([B, np.sqrt(nu) * np.eye(k)])
        rhs = np.zeros(A.shape[0])
        rhs[0] = beta1
        if not np.all(np.isfinite(A)):
            return None
        try:
            y = np.linalg.lstsq(A, rhs, rcond=None)[0]
        except np.linalg.LinAlgError:       # the SVD of an overflowing J (a penalty of 1e300 N/m): no step
            return None
        dx = V[:, :k] @ y
        return dx if np.all(np.isfinite(dx)) else None

    def lm_scale(self):
        """≈ trace(JᵀJ)/n = ‖J‖_F²/n, the LM damping's reference, by four
        Rademacher probes (E‖Jv‖² = ‖J‖_F²) — J is never formed."""
        n = self.op.shape[0]
        V = np.random.default_rng(0).choice((-1.0, 1.0), size=(n, 4))
        return max(float(np.sum(self.op.matmat(V) ** 2)) / (4 * n), 1e-300)
