"""Exact per-harmonic condensation onto relative contact DOFs (paper eq. 3–4).

Paper eq. 3 writes ``Z_r = (B H Bᵀ)⁻¹`` with ``H = D⁻¹``. A dovetail blade is
held only through its contact pairs, so at harmonic 0 ``D_0 = K`` is singular
(the blade floats) and ``H_0`` does not exist. We therefore change
coordinates first, ``q = T [u_r; y]`` with ``B T = [I, 0]``, so the relative
displacements are explicit unknowns, and take the Schur complement onto them:

    Z_r = D'_rr − D'_ry D'_yy⁻¹ D'_yr,     F_r = f'_r − D'_ry D'_yy⁻¹ f'_y,

with ``D' = Tᵀ D T``, ``f' = Tᵀ f``. ``D'_yy`` is the structure with the
interface tied, which is regular; where ``D`` is regular this equals eq. 3
exactly. The relative equations are then ``Z_r U_r + λ = F_r`` (eq. 3), with
λ the DLFT multiplier (sign: ``docs/contracts.md`` §6).

Complex harmonic amplitudes follow ``docs/contracts.md`` §3:
``D_j = K − (jω)² M + i jω C`` [N/m], ω in rad/s.

Cyclic models (tuned disk, :mod:`reduction.cyclic_reduce`): harmonic j
lives on nodal diameter ``(j·EO) mod N`` (Petrov 2004), so its ``D_j`` is
that ND's complex Hermitian sector model; :func:`relative_coordinates` of a
:class:`~reduction.cyclic_reduce.CyclicReducedModel` returns a
:class:`CyclicRelativeCoordinates` (one :class:`RelativeCoordinates` per ND)
and :func:`condense` / :func:`recover` pick each harmonic's own. ``D_j`` is
then Hermitian-based, not complex symmetric, and the ω-derivative uses the
general formula.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla
from scipy.linalg.blas import zsyrk

from workflow.engine.errors import BundleError
from workflow.engine.model import ReducedModel

#: Condense through the tied structure's modes (:func:`tied_basis`) wherever the damping is
#: Rayleigh; False: one LU of ``D'_yy`` per harmonic everywhere (the reference path of the tests).
TIED_BASIS = True
#: ‖C' − αM' − βK'‖_F / ‖C'‖_F at or below which C counts as Rayleigh damping. The project's
#: own bundles (``damping.alpha``, ``beta``, ``modal_ratio``: C = αM + βK before the reduction,
#: which is linear) reduce to 4e-14…5e-14 (quick and interface-scaling sectors).
RAYLEIGH_TOL = 1e-12


@dataclass
class RelativeCoordinates:
    """A reduced model rewritten in coordinates ``z = [u_r; y]`` (``q = T z``).

    Computed once per model; every frequency and harmonic reuses it.
    """

    M: np.ndarray  # Tᵀ M T
    K: np.ndarray
    C: np.ndarray
    f_static: np.ndarray  # Tᵀ f
    f_harmonic: np.ndarray
    O: np.ndarray  # O T: z → observed DOFs
    n_rel: int  # 3p
    # :func:`tied_basis`, made on first use: None not yet, False not applicable
    tied: object = field(default=None, repr=False, compare=False)

    def harmonic(self, j: int) -> "RelativeCoordinates":
        """The coordinates harmonic j is condensed in: the same for every j."""
        return self


def nodal_diameter_of_harmonic(n: int, engine_order: int, n_sectors: int) -> int:
    """ND ``(n·EO) mod N`` on which harmonic n of an EO travelling wave lives (Petrov 2004)."""
    return (int(n) * int(engine_order)) % int(n_sectors)


@dataclass
class CyclicRelativeCoordinates:
    """One :class:`RelativeCoordinates` per nodal diameter of a tuned disk.

    ``by_nd``: {ND k: coordinates of the ND-k sector model}; harmonic j uses
    ND ``(j·EO) mod N`` (:func:`nodal_diameter_of_harmonic`).
    The attributes the engine's *linear* parts read (``K``, ``M``, ``C``,
    ``O``, ``f_harmonic``, ``n_rel``: tied modes, band, the wear frequency)
    are those of harmonic 1's ND (the EO excitation's); ``f_static`` ND 0's.
    """

    by_nd: dict
    engine_order: int
    n_sectors: int

    def nodal_diameter(self, j: int) -> int:
        return nodal_diameter_of_harmonic(j, self.engine_order, self.n_sectors)

    def harmonic(self, j: int) -> RelativeCoordinates:
        k = self.nodal_diameter(j)
        if k not in self.by_nd:
            raise BundleError(f"cyclic reduced model has no nodal diameter {k} (harmonic {j} with engine order "
                              f"{self.engine_order} of {self.n_sectors} sectors): it was reduced for NDs "
                              f"{sorted(self.by_nd)} — rerun the reduction for more harmonics")
        return self.by_nd[k]

    def __getattr__(self, name):
        # the linear reference parts of the engine see the EO excitation's ND
        if name in ("K", "M", "C", "O", "f_harmonic", "n_rel"):
            return getattr(self.harmonic(1), name)
        if name == "f_static":
            return self.harmonic(0).f_static
        raise AttributeError(name)


@dataclass
class TiedBasis:
    """The tied structure ``D'_yy`` diagonalised once per model (real K, M; Rayleigh C).

    ``M_yy Φ = K_yy Φ diag(μ)`` with ``Φᵀ K_yy Φ = I`` (μ = 1/ω_k² of the tied modes, s²).
    With ``C = αM + βK``, ``D_j = a K − b M`` where ``a = 1 + i w β``, ``b = w² − i w α``,
    ``w = jω``, so at every frequency and harmonic

        D'_yy⁻¹ = Φ diag(1/(a − bμ)) Φᵀ,   Z_r = D'_rr − P diag(1/(a − bμ)) Pᵀ,
        P = D'_ry Φ = a K_ry Φ − b M_ry Φ,

    one complex symmetric rank-n_y update per harmonic (zsyrk) instead of an LU of D'_yy,
    its solve for the 3p columns of D'_yr and their product. K-orthonormal modes (the
    Cholesky of K_yy, not of M_yy) keep the static part exact: Z_r0 equals the LU's to
    5e-16, and the first harmonic at the tied resonance to 4e-13 (512 pairs; M-orthonormal
    modes: 4e-12 and 6e-8). ``PK = K_ry Φ``, ``PM = M_ry Φ`` (3p, n_y)."""

    alpha: float
    beta: float
    mu: np.ndarray
    Phi: np.ndarray
    PK: np.ndarray
    PM: np.ndarray
    # :func:`_high_mode_series`, made on first use: None not yet, False not worth it
    series: object = field(default=None, repr=False, compare=False)
    # ``O_y Φ`` of :func:`_recover_modal`, made on first use
    O_phi: np.ndarray | None = field(default=None, repr=False, compare=False)


#: Tied modes above ``SERIES_SPLIT`` × the first tied frequency enter Z_r through their
#: power series (:func:`_high_mode_series`); those below, through the rank update.
SERIES_SPLIT = 1000.0
#: Powers ``n = 0 … SERIES_TERMS − 1`` of the series are kept; a harmonic whose remainder
#: bound exceeds :data:`SERIES_TOL` takes the full rank update instead. With the split at
#: 1000×, the series serves harmonics up to ≈ 32× the first tied frequency.
SERIES_TERMS = 7
#: Relative remainder bound of the truncated series (round-off of the sum itself).
SERIES_TOL = 1e-17
#: Contact DOFs (3p) from which the series is built: below, the full rank update is
#: already cheap (16 pairs: 0.5 ms a frequency).
SERIES_MIN_DOFS = 192


@dataclass
class HighModeSeries:
    """The tied modes far above the excitation, summed once per model (:func:`_high_mode_series`).

    For a mode with ``|s μ_k| < 1``, ``s = b/a``, ``1/(a − bμ_k) = (1/a) Σ_n (s μ_k)ⁿ``, so the
    modes of ``high`` contribute to ``P diag(1/(a − bμ)) Pᵀ``

        Σ_n (s μ_c)ⁿ [a S_KK⁽ⁿ⁾ − b S_KM⁽ⁿ⁾ + (b²/a) S_MM⁽ⁿ⁾],
        S_KK⁽ⁿ⁾ = PK_h diag((μ_h/μ_c)ⁿ) PK_hᵀ,  S_KM⁽ⁿ⁾ = PK_h diag(·) PM_hᵀ + (·)ᵀ,  S_MM⁽ⁿ⁾ likewise,

    real symmetric (3p × 3p) matrices independent of the frequency: with ``K_rr`` and ``M_rr``
    they are ``S`` (2 + 3·SERIES_TERMS, 3p·3p), and a harmonic's Z_r is one real product of a
    few coefficients with ``S`` plus the rank update of the ``low`` modes. ``mu_c`` [s²]: the
    largest μ among the high modes (the scale of the powers, which keeps them far from
    underflow)."""

    low: np.ndarray
    mu_c: float
    S: np.ndarray


def tied_basis(rc: RelativeCoordinates) -> TiedBasis | None:
    """:class:`TiedBasis` of ``rc`` (made once, kept on ``rc.tied``), or None where the
    condensation keeps its LU per harmonic: :data:`TIED_BASIS` off, a complex (cyclic) or
    non-Rayleigh model, nothing to condense, or a K_yy that is not positive definite."""
    if not TIED_BASIS:
        return None
    if rc.tied is None:
        rc.tied = _tied_basis(rc) or False
    return rc.tied or None


def condensation(rc) -> str:
    """Which path :func:`condense` takes for ``rc``: "tied basis" or "LU per harmonic"."""
    return "tied basis" if isinstance(rc, RelativeCoordinates) and tied_basis(rc) is not None \
        else "LU per harmonic"


def rayleigh(M, K, C) -> tuple[float, float] | None:
    """(α, β) with C = αM + βK (least squares in the Frobenius norm, within :data:`RAYLEIGH_TOL`),
    or None where C is not of that form."""
    G = np.array([[np.vdot(M, M), np.vdot(M, K)], [np.vdot(K, M), np.vdot(K, K)]]).real
    alpha, beta = np.linalg.lstsq(G, np.real([np.vdot(M, C), np.vdot(K, C)]), rcond=None)[0]
    if np.linalg.norm(C - alpha * M - beta * K) > RAYLEIGH_TOL * np.linalg.norm(C):
        return None
    return float(alpha), float(beta)


def _tied_basis(rc: RelativeCoordinates) -> TiedBasis | None:
    r, n = rc.n_rel, rc.K.shape[0]
    K, M, C = rc.K, rc.M, rc.C
    if n == r or not all(np.isrealobj(a) for a in (K, M, C)):
        return None
    ab = rayleigh(M, K, C)
    if ab is None:
        return None
    alpha, beta = ab
    try:
        mu, Phi = sla.eigh(M[r:, r:], K[r:, r:], check_finite=False)
    except (np.linalg.LinAlgError, ValueError):   # K_yy not positive definite
        return None
    return TiedBasis(alpha=float(alpha), beta=float(beta), mu=mu, Phi=Phi, PK=K[:r, r:] @ Phi,
                     PM=M[:r, r:] @ Phi)


def _high_mode_series(rc: RelativeCoordinates, tm: TiedBasis) -> HighModeSeries | None:
    """:class:`HighModeSeries` of ``tm`` (kept on ``tm.series``), or None where the rank update
    is cheap (:data:`SERIES_MIN_DOFS`) or no tied mode lies above :data:`SERIES_SPLIT` × the first."""
    if tm.series is None:
        r = rc.n_rel
        mu_split = tm.mu.max() / SERIES_SPLIT ** 2
        high = tm.mu < mu_split
        if r < SERIES_MIN_DOFS or not high.any():
            tm.series = False
        else:
            mu_c = float(tm.mu[high].max())
            PK, PM, x = tm.PK[:, high], tm.PM[:, high], tm.mu[high] / mu_c
            S = np.empty((2 + 3 * SERIES_TERMS, r, r))
            S[0], S[1] = rc.K[:r, :r], rc.M[:r, :r]
            for n in range(SERIES_TERMS):
                w = x ** n
                Kw = PK * w
                S[2 + 3 * n] = Kw @ PK.T
                KM = Kw @ PM.T
                S[3 + 3 * n] = KM + KM.T
                S[4 + 3 * n] = (PM * w) @ PM.T
            tm.series = HighModeSeries(low=np.flatnonzero(~high), mu_c=mu_c, S=S.reshape(len(S), r * r))
    return tm.series or None


def _series_coefficients(a, b, da, db, mu_c: float, derivative: bool):
    """Coefficients of ``Z_r − (low modes' update) = c · S`` (:class:`HighModeSeries`) and of
    its derivative in w, or None where the series' remainder exceeds :data:`SERIES_TOL`.
    ``Z = a K_rr − b M_rr − Σ_n tⁿ (a S_KK⁽ⁿ⁾ − b S_KM⁽ⁿ⁾ + (b²/a) S_MM⁽ⁿ⁾)``, ``t = s μ_c``."""
    t = b / a * mu_c
    q = abs(t)
    # the remainder of the derivative's series, Σ_{n≥N} n qⁿ⁻¹ ≤ N q^(N−1)/(1 − q)², bounds the value's too
    if q >= 0.5 or SERIES_TERMS * q ** (SERIES_TERMS - 1) / (1 - q) ** 2 > SERIES_TOL:
        return None
    n = np.arange(SERIES_TERMS)
    tn = t ** n
    c = np.empty(2 + 3 * SERIES_TERMS, dtype=complex)
    c[0], c[1] = a, -b
    c[2::3], c[3::3], c[4::3] = -tn * a, tn * b, -tn * b * b / a
    if not derivative:
        return c, None
    dt = (db * a - b * da) / (a * a) * mu_c
    dtn = n * t ** np.maximum(n - 1, 0) * dt
    dc = np.empty_like(c)
    dc[0], dc[1] = da, -db
    dc[2::3] = -(dtn * a + tn * da)
    dc[3::3] = dtn * b + tn * db
    dc[4::3] = -(dtn * b * b / a + tn * (2 * b * db / a - b * b * da / (a * a)))
    return c, dc


def _ab(tm: TiedBasis, w: float):
    """(a, b) of ``D = aK − bM`` at w = jω [rad/s], and their derivatives in w."""
    return 1 + 1j * w * tm.beta, w * w - 1j * w * tm.alpha, 1j * tm.beta, 2 * w - 1j * tm.alpha


def _modal_terms(tm: TiedBasis, w: float):
    """``(a, b, da, db, a − bμ)`` at w = jω [rad/s], or None at an undamped tied resonance
    (a − bμ = 0 for some mode), where the LU path reports the singularity. ``P = D'_ry Φ =
    a PK − b PM`` is formed only where a product with all of it is needed (:func:`_p_times`)."""
    a, b, da, db = _ab(tm, w)
    den = a - b * tm.mu
    if not np.all(den != 0):
        return None
    return a, b, da, db, den


def _stacked_terms(tm: TiedBasis, omega: float, harmonics):
    """:func:`_modal_terms` of ``harmonics`` (m of them) at ω [rad/s] and their stacks: (terms,
    a (m,), b (m,), 1/(a − bμ) (n_y, m)), or None at an undamped tied resonance of one of them."""
    terms = [_modal_terms(tm, j * omega) for j in harmonics]
    if any(t is None for t in terms):
        return None
    return (terms, np.array([t[0] for t in terms]), np.array([t[1] for t in terms]),
            1.0 / np.stack([t[4] for t in terms], axis=1))


def _real_times(A: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """A Z for a real matrix A and complex columns Z (n, k), as one real product that reads A once."""
    k = Z.shape[1]
    X = A @ np.concatenate([Z.real, Z.imag], axis=1)
    return X[:, :k] + 1j * X[:, k:]


def _p_times(tm: TiedBasis, a, b, z: np.ndarray, transpose: bool = False) -> np.ndarray:
    """``P z = (a PK − b PM) z`` (``Pᵀ z`` if ``transpose``) for a complex vector z, or for the
    columns of z (n, k) with a, b (k,) — one harmonic a column — without forming the complex P:
    real products that read PK and PM once each."""
    K, M = (tm.PK.T, tm.PM.T) if transpose else (tm.PK, tm.PM)
    Z = z[:, None] if z.ndim == 1 else z
    out = a * _real_times(K, Z) - b * _real_times(M, Z)
    return out[:, 0] if z.ndim == 1 else out


@dataclass
class Condensed:
    """Per-harmonic condensed dynamic stiffness and load at one ω.

    ``Zr``: (Nh+1, 3p, 3p) complex [N/m]; ``Fr``: (Nh+1, 3p) complex [N];
    ``dZr``, ``dFr``: their derivatives with respect to ω [per rad/s], or None.
    ``compliance``: ``Zr`` holds Z_0 and the compliances H_j = Z_j⁻¹ [m/N] of harmonics j ≥ 1
    (the engine's compliance form), with ``stiffness(j, U_j)`` → Z_j U_j [N].
    """

    omega: float
    Zr: np.ndarray
    Fr: np.ndarray
    dZr: np.ndarray | None = None
    dFr: np.ndarray | None = None
    compliance: bool = False
    stiffness: object = None

    @property
    def nh(self) -> int:
        return self.Zr.shape[0] - 1


def relative_coordinates(model):
    """Relative coordinates of a :class:`ReducedModel`, or of every ND of a
    cyclic model (:class:`CyclicRelativeCoordinates`): the one place that
    tells the two apart.

    A model's coordinates (and their :func:`tied_basis`) are made once and kept while the
    model lives and holds the same arrays (a stage asks for them in the penalty choice, the
    sweep and the checks). Its arrays are never modified in place (``dataclasses.replace``
    makes a new model). A model that shares M, K, C, B and O with a kept one and differs in its
    loads (a scaled excitation) shares its coordinates and tied basis: only Tᵀ f is new."""
    if getattr(model, "is_cyclic", False):
        return CyclicRelativeCoordinates(by_nd={k: _relative(m)[0] for k, m in model.models.items()},
                                         engine_order=model.engine_order, n_sectors=model.n_sectors)
    arrays = tuple(getattr(model, n) for n in _DEFINING)
    kept = _KEPT.get(id(model))
    if kept is not None and kept[0]() is model and all(a is b for a, b in zip(kept[1], arrays)):
        return kept[2]
    twin = next((k for k in _KEPT.values() if k[0]() is not None
                 and all(a is b for a, b in zip(k[1][:_SHARED], arrays[:_SHARED]))), None)
    if twin is not None:
        T = twin[3]
        rc, T = replace(twin[2], f_static=T.T @ model.f_static, f_harmonic=T.T @ model.f_harmonic), T
    else:
        rc, T = _relative(model)
    _KEPT[id(model)] = (weakref.ref(model), arrays, rc, T)
    weakref.finalize(model, _KEPT.pop, id(model), None)
    return rc


def coordinate_basis(model: ReducedModel) -> np.ndarray:
    """T (m, m) with ``q = T z`` for the coordinates ``z = [u_r; y]`` of
    :func:`relative_coordinates` (model), dense: the same T its matrices were made with."""
    relative_coordinates(model)             # made and kept, with its T, if not yet
    T = _KEPT[id(model)][3]
    return T if isinstance(T, np.ndarray) else T.toarray()


#: the arrays a model's relative coordinates are made from (:func:`relative_coordinates`); the
#: first :data:`_SHARED` make T and the transformed matrices, the others are loads
_DEFINING = ("M", "K", "C", "B", "O", "f_static", "f_harmonic")
_SHARED = 5
#: id(model) → (weak reference to it, its arrays then, its RelativeCoordinates, its T: sparse or dense)
_KEPT: dict = {}
#: the largest set of model coordinates coupled through B's rows that :func:`_blockwise_t` takes
#: (node-to-node pairs: 6, a blade and a disk node); past it the dense QR of the whole Bᵀ
BLOCK_MAX = 64


def _blockwise_t(B: np.ndarray):
    """Sparse T (m, m) with ``B T = [I, 0]``, or None where B does not split into small blocks.

    B's rows and columns split into independent sets (connected through its nonzeros: a pair's
    rows and its two nodes' DOFs). Per set, the QR of its block Bᵀ_c = Q R gives columns Q R⁻ᵀ
    for its relative DOFs and an orthonormal basis Q₂ of its null space; the model coordinates
    no row touches (modes) are their own null columns. ``T_r = Bᵀ(BBᵀ)⁻¹`` as from the QR of the
    whole Bᵀ, and the null basis is orthonormal (another rotation of the same space), so the
    coordinates are :func:`_relative`'s dense ones up to that rotation; T has ≤ BLOCK_MAX
    entries a column, and TᵀMT costs O(m² · BLOCK_MAX) instead of O(m³) (544 pairs: 1.5 s
    against 7.6 s for the dense QR and products, one thread)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    n_rel, m = B.shape
    Bs = sp.csr_matrix(B)
    if np.any(np.diff(Bs.indptr) == 0):
        raise ValueError("relative-displacement map B is rank deficient: a pair without DOFs?")
    graph = sp.bmat([[None, Bs], [Bs.T, None]], format="csr")
    _, label = connected_components(graph, directed=False)
    row_lab, col_lab = label[:n_rel], label[n_rel:]
    order = np.argsort(col_lab, kind="stable")
    bounds = np.flatnonzero(np.diff(col_lab[order])) + 1
    rows_of = {}
    for i, c in enumerate(row_lab):
        rows_of.setdefault(c, []).append(i)
    ri, ci, vals, diag = [], [], [], []
    null_col = n_rel
    for cols in np.split(order, bounds):
        rows = rows_of.get(col_lab[cols[0]], [])
        if not rows:                               # coordinates no row touches: their own null columns
            ri.append(cols)
            ci.append(np.arange(null_col, null_col + cols.size))
            vals.append(np.ones(cols.size))
            null_col += cols.size
            continue
        if cols.size > BLOCK_MAX:
            return None
        Q, R = np.linalg.qr(B[np.ix_(rows, cols)].T, mode="complete")
        nr = len(rows)
        if nr > cols.size:
            raise ValueError("relative-displacement map B is rank deficient: two pairs share DOFs?")
        diag.append(np.abs(np.diag(R[:nr])))
        Tr = sla.solve_triangular(R[:nr], Q[:, :nr].T, lower=False).T      # Q R⁻ᵀ, (cols, nr)
        nn = cols.size - nr
        ri.append(np.repeat(cols, cols.size))
        ci.append(np.tile(np.concatenate([rows, np.arange(null_col, null_col + nn)]), cols.size))
        vals.append(np.concatenate([Tr, Q[:, nr:]], axis=1).ravel())
        null_col += nn
    d = np.concatenate(diag) if diag else np.ones(1)
    if d.size and np.min(d) <= 1e-12 * np.max(d):
        raise ValueError("relative-displacement map B is rank deficient: two pairs share DOFs?")
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(ri), np.concatenate(ci))), shape=(m, m))
    T.eliminate_zeros()
    return T


def _relative(model: ReducedModel):
    """(coordinates, T): ``T`` with ``B T = [I, 0]``, by blocks where B splits into small ones
    (:func:`_blockwise_t`, sparse), else from a QR factorisation of the whole ``Bᵀ`` (dense).

    ``B = Rᵀ Qᵀ`` (economy QR of Bᵀ, B of full row rank 3p, real), so
    ``T = [Q R⁻ᵀ, N]`` with N an orthonormal basis of null(B). T is real,
    so ``Tᵀ D T`` keeps a Hermitian D Hermitian.
    """
    B = model.B
    n_rel, m = B.shape
    T = _blockwise_t(B) if n_rel else None
    if T is not None:
        def congruent(X):
            Y = np.asarray((T.T @ X.T).T)          # X T
            return np.asarray(T.T @ Y)
        return RelativeCoordinates(M=congruent(model.M), K=congruent(model.K), C=congruent(model.C),
                                   f_static=T.T @ model.f_static, f_harmonic=T.T @ model.f_harmonic,
                                   O=np.asarray((T.T @ model.O.T).T), n_rel=n_rel), T
    Q, R = np.linalg.qr(B.T, mode="complete")
    Rr = R[:n_rel]
    if n_rel and np.min(np.abs(np.diag(Rr))) <= 1e-12 * np.max(np.abs(np.diag(Rr))):
        raise ValueError("relative-displacement map B is rank deficient: two pairs share DOFs?")
    T = np.empty((m, m))
    T[:, :n_rel] = sla.solve_triangular(Rr, Q[:, :n_rel].T, lower=False).T  # Q R⁻ᵀ
    T[:, n_rel:] = Q[:, n_rel:]
    return RelativeCoordinates(M=T.T @ model.M @ T, K=T.T @ model.K @ T, C=T.T @ model.C @ T,
                               f_static=T.T @ model.f_static, f_harmonic=T.T @ model.f_harmonic,
                               O=model.O @ T, n_rel=n_rel), T


def dynamic_stiffness(rc: RelativeCoordinates, j: int, omega: float,
                      derivative: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``D_j`` and ``∂D_j/∂ω`` (None unless ``derivative``) in relative coordinates
    (paper eq. 4, complex form). Written into one complex array: forming the dense D
    was a tenth of a 256-pair sweep's time through NumPy's temporaries (and ∂D/∂ω,
    formed whether used or not, as much again)."""
    w = j * omega
    D = np.empty(rc.K.shape, dtype=complex)
    if np.isrealobj(rc.K) and np.isrealobj(rc.M) and np.isrealobj(rc.C):
        np.multiply(rc.M, -w * w, out=D.real)
        D.real += rc.K
        np.multiply(rc.C, w, out=D.imag)
    else:   # a cyclic ND's Hermitian sector operators are complex
        np.multiply(rc.M, -w * w, out=D)
        D += rc.K
        D += (1j * w) * rc.C
    dD = (-2.0 * j * w * rc.M + 1j * j * rc.C) if derivative else None
    return D, dD


def harmonic_load(rc: RelativeCoordinates, j: int) -> np.ndarray:
    """Complex amplitude of the load at harmonic j: static at 0, cos(ωt) force at 1."""
    if j == 0:
        return rc.f_static.astype(complex)
    if j == 1:
        return rc.f_harmonic.astype(complex)
    return np.zeros(rc.M.shape[0], dtype=complex)


def condense(rc, omega: float, nh: int, derivative: bool = False) -> Condensed:
    """Condense onto relative DOFs for harmonics 0…nh at ω [rad/s] (eq. 3).

    ``rc``: :class:`RelativeCoordinates`, or :class:`CyclicRelativeCoordinates`
    (harmonic j on its own ND), or a whole disk's
    :class:`reduction.mistuned.WholeDiskCoordinates`, which condenses itself. One LU of
    ``D'_yy`` per harmonic serves Z_r, F_r and their ω-derivatives.
    """
    if getattr(rc, "is_whole_disk", False):
        return rc.condense(omega, nh, derivative)
    r = rc.harmonic(0).n_rel
    if not derivative and isinstance(rc, RelativeCoordinates):
        out = _condense_all(rc, omega, nh)
        if out is not None:
            return out
    Zr = np.empty((nh + 1, r, r), dtype=complex)
    Fr = np.empty((nh + 1, r), dtype=complex)
    dZr = np.empty_like(Zr) if derivative else None
    dFr = np.empty_like(Fr) if derivative else None
    for j in range(nh + 1):
        out = _condense_harmonic(rc.harmonic(j), j, omega, derivative)
        Zr[j], Fr[j] = out[0], out[1]
        if derivative:
            dZr[j], dFr[j] = out[2], out[3]
    return Condensed(omega=omega, Zr=Zr, Fr=Fr, dZr=dZr, dFr=dFr)


#: Columns of the series stack per product in :func:`_condense_all` (bounds its scratch to
#: 2(Nh+1) × this many doubles).
CHUNK = 1 << 18


def _condense_all(rc: RelativeCoordinates, omega: float, nh: int) -> Condensed | None:
    """:func:`condense` of harmonics 0…nh at once where every harmonic takes the high-mode series
    (:class:`HighModeSeries`; None otherwise): the series' coefficients of all harmonics meet its
    stack S in one real product, which reads S (434 MB at 512 pairs) once instead of once per
    harmonic, and the load terms Φᵀ f_y and P g are products with all harmonics' columns."""
    tm = tied_basis(rc)
    series = None if tm is None else _high_mode_series(rc, tm)
    if series is None:
        return None
    stacked = _stacked_terms(tm, omega, range(nh + 1))
    if stacked is None:
        return None
    terms, a, b, d = stacked
    coef = [_series_coefficients(t[0], t[1], t[2], t[3], series.mu_c, False) for t in terms]
    if any(c is None for c in coef):
        return None
    r, m = rc.n_rel, nh + 1
    C = np.stack([c for c, _ in coef])                                   # (Nh+1, len(S))
    G = np.concatenate([C.real, C.imag])
    Zr = np.empty((m, r, r), dtype=complex)
    flat = Zr.reshape(m, r * r)
    for k in range(0, r * r, CHUNK):
        X = G @ series.S[:, k:k + CHUNK]
        flat.real[:, k:k + CHUNK], flat.imag[:, k:k + CHUNK] = X[:m], X[m:]
    low = series.low
    for j in range(m):
        Pk = a[j] * tm.PK[:, low] - b[j] * tm.PM[:, low]
        Zr[j] -= (Pk * d[low, j]) @ Pk.T
    fy = np.stack([harmonic_load(rc, j) for j in range(m)], axis=1)      # (n, Nh+1)
    g = d * _real_times(tm.Phi.T, fy[r:])                                # Φᵀ f_y / (a − bμ)
    Fr = (fy[:r] - _p_times(tm, a, b, g)).T
    return Condensed(omega=omega, Zr=Zr, Fr=np.ascontiguousarray(Fr))


def diagonal(rc, omega: float, nh: int) -> np.ndarray:
    """The diagonals of Z_r for harmonics 0…nh at ω [rad/s], (nh+1, 3p) complex [N/m], without
    forming Z_r where :class:`TiedBasis` applies: ``Z_ii = a K_ii − b M_ii − Σ_k P_ik² / (a − bμ_k)``
    with ``P = a PK − b PM``, three real products for all harmonics (at 512 pairs and 33
    harmonics 5.2 s through :func:`condense` and 1.2 GB). Else the diagonals of :func:`condense`."""
    tm = tied_basis(rc) if isinstance(rc, RelativeCoordinates) else None
    stacked = None if tm is None else _stacked_terms(tm, omega, range(nh + 1))
    if stacked is None:
        return np.diagonal(condense(rc, omega, nh).Zr, axis1=1, axis2=2).copy()
    r = rc.n_rel
    _, a, b, d = stacked
    kk = _real_times(tm.PK * tm.PK, d)
    km = _real_times(tm.PK * tm.PM, d)
    mm = _real_times(tm.PM * tm.PM, d)
    out = a * np.diag(rc.K)[:r, None] - b * np.diag(rc.M)[:r, None] - (a * a * kk - 2 * a * b * km + b * b * mm)
    return np.ascontiguousarray(out.T)


def _condense_harmonic(rc: RelativeCoordinates, j: int, omega: float, derivative: bool):
    """(Z_r, F_r[, dZ_r/dω, dF_r/dω]) of harmonic j: the Schur complement onto u_r."""
    tm = tied_basis(rc)
    if tm is not None:
        out = _condense_modal(rc, tm, j, omega, derivative)
        if out is not None:
            return out
    r = rc.n_rel
    D, dD = dynamic_stiffness(rc, j, omega, derivative)
    f = harmonic_load(rc, j)
    if D.shape[0] == r:
        # every coordinate is a relative contact DOF (e.g. Den Hartog's oscillator):
        # nothing to condense, and LAPACK refuses an empty factorisation
        return D, f, dD, np.zeros(r, dtype=complex)
    lu = sla.lu_factor(D[r:, r:], check_finite=False)
    rhs = np.concatenate([D[r:, :r], f[r:, None]], axis=1)
    sol = sla.lu_solve(lu, rhs, check_finite=False)
    A, b = sol[:, :r], sol[:, r]  # D_yy⁻¹ D_yr, D_yy⁻¹ f_y
    Z = D[:r, :r] - D[:r, r:] @ A
    F = f[:r] - D[:r, r:] @ b
    if not derivative:
        return Z, F
    if np.isrealobj(rc.K):
        # D complex symmetric (real K, M, C), so D_ry D_yy⁻¹ = Aᵀ.
        L = A.T
    else:
        # a cyclic ND's Hermitian sector model: D_ry D_yy⁻¹ = (D_yy⁻ᵀ D_ryᵀ)ᵀ, one transposed solve
        L = sla.lu_solve(lu, D[:r, r:].T, trans=1, check_finite=False).T
    dZ = dD[:r, :r] - dD[:r, r:] @ A - L @ dD[r:, :r] + L @ dD[r:, r:] @ A
    dF = -dD[:r, r:] @ b + L @ (dD[r:, r:] @ b)
    return Z, F, dZ, dF


def _condense_modal(rc: RelativeCoordinates, tm: TiedBasis, j: int, omega: float, derivative: bool):
    """:func:`_condense_harmonic` through :class:`TiedBasis`; None at an undamped tied
    resonance (a − bμ = 0), which the LU path reports as singular. The modes far above the
    harmonic enter through :class:`HighModeSeries` where it applies (one real product with
    its stack), the others through a rank update."""
    r = rc.n_rel
    terms = _modal_terms(tm, j * omega)
    if terms is None:
        return None
    a, b, da, db, den = terms
    d = 1.0 / den
    if not np.all(np.isfinite(d)):
        return None
    series = _high_mode_series(rc, tm)
    coef = None if series is None else _series_coefficients(a, b, da, db, series.mu_c, derivative)
    # the modes of the rank update: all of them, or the low ones beside the series
    k = slice(None) if coef is None else series.low
    Pk, dk = a * tm.PK[:, k] - b * tm.PM[:, k], d[k]
    Pd = Pk * dk
    if coef is None:
        up = np.triu(zsyrk(1.0, Pk * np.sqrt(dk), trans=0, lower=0))   # P diag(d) Pᵀ, complex symmetric
        Z = a * rc.K[:r, :r] - b * rc.M[:r, :r] - up - np.triu(up, 1).T
    else:
        parts = _combine(np.array([c for c in coef if c is not None]), series.S, r)
        Z = parts[0]
        Z -= Pd @ Pk.T
    f = harmonic_load(rc, j)
    h = tm.Phi.T @ f[r:]                                          # Φᵀ f_y
    g = d * h
    F = f[:r] - _p_times(tm, a, b, g)
    if not derivative:
        return Z, F
    # d/dω = j d/dw
    dP = da * tm.PK[:, k] - db * tm.PM[:, k]
    dd = -(da - db * tm.mu) * d * d
    dZ = (da * rc.K[:r, :r] - db * rc.M[:r, :r]) if coef is None else parts[1]
    dZ = j * (dZ - dP @ Pd.T - Pd @ dP.T - (Pk * dd[k]) @ Pk.T)
    dF = j * -(_p_times(tm, da, db, g) + _p_times(tm, a, b, dd * h))
    return Z, F, dZ, dF


def _combine(c: np.ndarray, S: np.ndarray, r: int) -> list:
    """``[Σ_i c[k, i] S_i for k]`` (r × r complex views) for complex coefficients c (k, m) and the
    real stack S (m, r·r): one real product, written straight into the complex result, that
    reads S once (it is memory-bound: 434 MB at 512 pairs)."""
    n = len(c)
    out = np.empty((S.shape[1], n), dtype=complex)
    # columns Re c_0, Im c_0, Re c_1, …: the float layout of the complex columns of ``out``
    np.dot(S.T, np.column_stack([x for k in range(n) for x in (c[k].real, c[k].imag)]), out=out.view(float))
    return [out[:, k].reshape(r, r) for k in range(n)]


def recover(rc, omega: float, Ur: np.ndarray) -> np.ndarray:
    """Observed response harmonics (Nh+1, n_obs) from relative ones ``Ur`` (Nh+1, 3p).

    Solves the tied remainder ``D'_yy y = f'_y − D'_yr u_r`` per harmonic (on
    its own ND for a cyclic ``rc``: sector 0's complex amplitudes) and maps
    ``z = [u_r; y]`` to the observed DOFs; a whole disk recovers itself (every blade's).
    """
    if getattr(rc, "is_whole_disk", False):
        return rc.recover(omega, Ur)
    if isinstance(rc, RelativeCoordinates):
        tm = tied_basis(rc)
        out = None if tm is None else _recover_modal(rc, tm, omega, np.asarray(Ur), range(Ur.shape[0]))
        if out is not None:
            return out
    out = np.empty((Ur.shape[0], rc.harmonic(0).O.shape[0]), dtype=complex)
    for j in range(Ur.shape[0]):
        rj = rc.harmonic(j)
        tm = tied_basis(rj)
        row = None if tm is None else _recover_modal(rj, tm, omega, Ur[j:j + 1], [j])
        if row is not None:
            out[j] = row[0]
            continue
        r = rj.n_rel
        f = harmonic_load(rj, j)
        D, _ = dynamic_stiffness(rj, j, omega, derivative=False)
        y = np.linalg.solve(D[r:, r:], f[r:] - D[r:, :r] @ Ur[j]) if D.shape[0] > r else np.zeros(0, complex)
        out[j] = rj.O[:, :r] @ Ur[j] + rj.O[:, r:] @ y
    return out


def recover_map(rc, omega: float, j: int = 1):
    """(C (n_obs, 3p), d (n_obs,)) complex with ``recover(rc, ω, Ur)[j] = C Ur[j] + d`` [m]: the
    affine map :func:`recover` applies at harmonic j ≥ 0 and ω [rad/s], formed through the tied
    basis in one pass over PK and PM (:func:`_recover_modal` with the identity for Ur:
    ``C = O_r − (O_y Φ) diag(1/(a − bμ)) Pᵀ``, ``d = (O_y Φ) diag(1/(a − bμ)) Φᵀ f_y``). At 544 pairs
    this replaces 3p + 1 recoveries (48 s) by two products of (3p, n_y) matrices. None where
    :func:`recover` takes another path: no tied basis (LU condensation, cyclic or whole-disk
    coordinates) or an undamped tied resonance."""
    if not isinstance(rc, RelativeCoordinates):
        return None
    tm = tied_basis(rc)
    stacked = None if tm is None else _stacked_terms(tm, omega, [j])
    if stacked is None:
        return None
    _, a, b, dv = stacked
    r = rc.n_rel
    if tm.O_phi is None:
        tm.O_phi = rc.O[:, r:] @ tm.Phi
    W = tm.O_phi * dv[:, 0]                        # (O_y Φ) diag(1/(a − bμ)), (n_obs, n_y)
    C = rc.O[:, :r] - (a[0] * _real_times(tm.PK, W.T) - b[0] * _real_times(tm.PM, W.T)).T
    d = W @ _real_times(tm.Phi.T, harmonic_load(rc, j)[r:, None])[:, 0]
    return C, d


def _recover_modal(rc: RelativeCoordinates, tm: TiedBasis, omega: float, Ur: np.ndarray, harmonics):
    """:func:`recover` through :class:`TiedBasis` for the rows of Ur, harmonics ``harmonics``,
    at once (None at an undamped tied resonance of one of them): ``O z = O_r u_j + (O_y Φ)
    diag(1/(a_j − b_j μ)) (Φᵀ f_yj − a_j PKᵀ u_j + b_j PMᵀ u_j)`` (Φᵀ D'_yr u = Pᵀ u, D
    symmetric). PK, PM and Φ are read once for all harmonics instead of once per harmonic, and
    ``O_y Φ`` (n_obs × n_y) is kept on ``tm``: at 512 pairs the per-harmonic solves were 7 %
    of a sweep's time."""
    r = rc.n_rel
    stacked = _stacked_terms(tm, omega, harmonics)
    if stacked is None:
        return None
    _, a, b, d = stacked
    if tm.O_phi is None:
        tm.O_phi = rc.O[:, r:] @ tm.Phi
    fy = np.stack([harmonic_load(rc, j)[r:] for j in harmonics], axis=1)
    q = d * (_real_times(tm.Phi.T, fy) - _p_times(tm, a, b, Ur.T, transpose=True))
    return (rc.O[:, :r] @ Ur.T + tm.O_phi @ q).T
