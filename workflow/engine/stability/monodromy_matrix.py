"""The monodromy matrix of the linearised periodic system (:mod:`workflow.engine.stability.tangent`),
integrated over one period by backward Euler on the tangent's pieces (:func:`monodromy`).

The pieces are the DLFT's samples with each stick/slip/separation switch located inside its
sample interval (:func:`workflow.engine.stability.switches._switch_pieces`). Measured against
event-driven shooting (2026-11-28, :mod:`workflow.verification.floquet`; the 1-DOF Jenkins
oscillator of tests/workflow/test_stability.py, HB Nh = 15, nit = 128): 7.7e-5 at ω = 1.3 and
3.7e-4 at ω = 1.2 (normal load varying) at the defaults, against 1.26e-3 and 4.9e-4 with the
switches at the samples. What is left is not the monodromy's: ε of the tangent (10⁴ → 10⁶
moves it by 7e-5 on both) and, at ω = 1.2, the HB orbit itself (its AFT on 128 samples: with
1024 and Nh = 31 the error is 8.8e-5, ε's part); the monodromy's own part, nit = 1024…8192 and
refine = 64…256 against 8192 and 256, is below 5.5e-5. The defaults since 2026-11-29 (nit =
256, the switches cut into 8 three times, backward Euler extrapolated twice: ``MONODROMY_NIT``,
``SWITCH_REFINE``, :data:`RICHARDSON`) give 7.4e-5 and 3.7e-4.

The monodromy is integrated through its structure (the anchors' 2×2 blocks eliminated pair by
pair, :func:`_step_operators`) and only on the states that are not slaved at the period's
start (:func:`_live_multipliers`): at 128 pairs 18 columns instead of 238.

SI units: M kg, K N/m, C N·s/m, ω rad/s, durations s.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from workflow.engine.jit import compiled

#: backward-Euler steps a sample interval in :func:`monodromy` (Richardson-extrapolated)
SUBSTEPS = 1


#: Richardson's halvings of the monodromy's backward-Euler step (:func:`_extrapolated`): 2 removes
#: the h and h² terms, 1, 2 and 4 steps a piece
RICHARDSON = 2


def monodromy(M, C, K, B, tan: dict, omega: float, *, substeps: int = SUBSTEPS, richardson: bool = True,
              h=None, levels: int = RICHARDSON) -> np.ndarray:
    """Monodromy matrix (dimensionless, (2m + na)²) of the linearised periodic system of the
    module docstring, ``E(t) ż = A(t) z`` with z = [δq, δv, δw], by time integration over one
    period with the tangent's coefficients (:func:`tangent_blocks`, ``tan``) constant on each of
    its pieces: ``h`` (n,) s the pieces' durations in order (sum T; default the nit uniform
    intervals T/nit). Backward Euler, ``substeps`` a piece, extrapolated unless ``richardson``
    is False (Richardson, ``levels`` halvings: 2·Z(h/2) − Z(h) at 1, eliminating h and h² at 2,
    :func:`_extrapolated`). Backward Euler is the one-step method that
    handles the algebraic slip rows (E singular, index 1): the step that enters slip projects δw
    onto the cone's constraint — the saltation of the exact law. Its error: O(h²) after
    extrapolation, and that of the switching instants, which the pieces carry
    (:func:`_switch_pieces`: to T/(nit·refine)). M, C, K (m, m), B (3p, m). Each step is solved
    through its structure (:func:`_step_operators`); :func:`_live_multipliers` integrates only
    the states that are not slaved at the start."""
    m = M.shape[0]
    n = 2 * m + 2 * len(tan.get("idx", ()))
    h = _durations(tan, omega, h)
    subs = _substeps(substeps, levels if richardson else 0)
    return _extrapolated(_propagate(M, C, K, B, tan, h, subs, np.arange(len(h)), np.arange(n)))


def _substeps(substeps: int, levels: int) -> list:
    """Backward-Euler steps a piece of Richardson's table (:func:`_extrapolated`): substeps·2^j, j ≤ levels."""
    return [int(substeps) * 2 ** j for j in range(int(levels) + 1)]


def _extrapolated(Zs: list) -> np.ndarray:
    """Richardson's extrapolation of the monodromies ``Zs`` by backward Euler at s, 2s, … 2^levels·s
    steps a piece (:func:`_substeps`): Neville's table T_{j,k} = T_{j,k−1} + (T_{j,k−1} − T_{j−1,k−1})/(2^k − 1)
    removes the h^k term of the error at column k (backward Euler's error has every power of h,
    its step on a piece of constant coefficients being a rational function of h). Each of the
    terms is L-stable (→ 0 for a stiff mode), and so is their combination."""
    T = [Zs[0]]
    for j in range(1, len(Zs)):
        row = [Zs[j]]
        for k in range(1, j + 1):
            row.append(row[k - 1] + (row[k - 1] - T[k - 1]) / (2 ** k - 1))
        T = row
    return T[-1]


def _durations(tan: dict, omega: float, h) -> np.ndarray:
    """The pieces' durations (s): ``h``, checked, or the nit uniform intervals T/nit."""
    nit = tan["Kp"].shape[0]
    h = np.full(nit, 2 * np.pi / omega / nit) if h is None else np.asarray(h, dtype=float)
    if h.shape != (nit,):
        raise ValueError(f"monodromy: {h.shape} durations for {nit} tangent pieces")
    return h


def _live_multipliers(M, C, K, B, tan: dict, omega: float, *, substeps: int = SUBSTEPS, h=None,
                      levels: int = RICHARDSON) -> np.ndarray:
    """The nonzero Floquet multipliers of :func:`monodromy` (with as many zeros as it takes), at a
    fraction of its cost: the period starts at the piece with the fewest pairs in contact (the
    eigenvalues of Φ(T + t₀, t₀) = Φ(t₀, 0)Φ(T, t₀) and of Φ(T, 0) = Φ(T, t₀)Φ(t₀, 0) are the
    same), and only the states that are not slaved there are integrated: δq, δv and the anchors
    of the pairs in contact. A separated pair's anchor is slaved (δw = δu_T: its column of the
    monodromy is zero), so the monodromy is block-triangular and its nonzero eigenvalues are
    those of the live block. At 128 pairs (Ritz size 7, 112 anchors) 18 columns instead of 238."""
    m = M.shape[0]
    h = _durations(tan, omega, h)
    idx = tan.get("idx", np.zeros(0, int))
    contact = tan.get("contact", np.zeros((len(h), 0), bool))
    k0 = int(np.argmin(contact.sum(axis=1))) if len(idx) else 0
    order = (k0 + np.arange(len(h))) % len(h)
    a = np.flatnonzero(contact[k0])
    cols = np.concatenate([np.arange(2 * m), 2 * m + np.stack([2 * a, 2 * a + 1], axis=1).ravel()]).astype(int)
    Z = _extrapolated(_propagate(M, C, K, B, tan, h[order], _substeps(substeps, levels), order, cols))
    return np.linalg.eigvals(Z[cols])


#: pieces whose step operators :func:`_propagate` holds at once (memory: at 128 pairs, Ritz size 7, 4 MB)
_CHUNK = 256


def _propagate(M, C, K, B, tan: dict, h: np.ndarray, subs, order: np.ndarray, cols: np.ndarray) -> list:
    """[Z (n, len(cols)) for s in ``subs``]: the columns ``cols`` of the identity carried over the
    pieces ``order`` of ``tan`` (durations ``h``, s, in that order) by s backward-Euler steps a
    piece (:func:`_step_operators`). Every s in one sweep over the pieces: the law's blocks, which
    do not depend on the step, are prepared once a chunk for all of them (:func:`_law_blocks`). A
    separated pair's anchor rows are slaved (δw = δu_T): they are not carried but set from δq when
    the pair touches again (``touch``, :func:`_index_rows`) and at the end."""
    m = M.shape[0]
    Bd = np.asarray(B.toarray() if sp.issparse(B) else B, dtype=float)
    Bp = Bd.reshape(-1, 3, m)                                   # (p, 3, m): each pair's rows of B
    idx = tan.get("idx", np.zeros(0, int))
    contact = tan.get("contact", np.ones((len(order), 0), bool))[order]
    BT = Bp[idx, 1:, :]                                         # (pa, 2, m): δu_T of the anchors' pairs
    n = 2 * m + 2 * len(idx)
    touch = np.zeros_like(contact)
    touch[1:] = contact[1:] & ~contact[:-1]                     # the pairs that touch again at the piece
    ptr, rows, ta = _index_rows(touch, m)
    slaved = BT[ta].reshape(-1, m)                              # their rows δw = B_T δq
    Zs = [np.eye(n)[:, cols] for _ in subs]
    v1 = np.empty((m, len(cols)))
    for lo in range(0, len(order), _CHUNK):     # the step operators of a chunk of pieces at a time (memory)
        law = _law_blocks(K, Bp, tan, order[lo:lo + _CHUNK])
        for Z, sub in zip(Zs, subs):
            ops = _step_operators(M, C, law, h[lo:lo + _CHUNK] / sub)
            if _pieces_numba is not None:
                _pieces_numba(Z, ops["Av"], ops["hs"], ops["ptr"], ops.get("rows", _NO_ROWS),
                              ops.get("D", _NO_D), ops.get("P", np.zeros((0, m))),
                              np.ascontiguousarray(ptr[lo:lo + len(ops["hs"]) + 1]), rows, slaved,
                              ops.get("wptr", np.zeros(len(ops["hs"]) + 1, np.int64)), ops.get("wrows", _NO_ROWS),
                              int(sub), m)
                continue
            for j in range(len(ops["hs"])):
                k = lo + j
                if ptr[k + 1] > ptr[k]:     # the anchors of the pairs that touch again start from their slaved value
                    r = slice(2 * ptr[k], 2 * ptr[k + 1])
                    Z[rows[r]] = slaved[r] @ Z[:m]
                for _ in range(sub):
                    _step(Z, v1, ops, j, m)
    for Z in Zs:
        _slave(Z, ~contact[-1], BT, m)
    return Zs


def _index_rows(mask: np.ndarray, m: int):
    """(ptr (n+1,), rows (2e,), a (e,)) of the entries (k, a) of ``mask`` (n, pa) bool in order of k:
    piece k's are e ∈ [ptr[k], ptr[k+1]), their anchors a and rows 2m + 2a, 2m + 2a + 1 of the state."""
    k, a = np.nonzero(mask)
    ptr = np.searchsorted(k, np.arange(mask.shape[0] + 1))
    return ptr, 2 * m + np.stack([2 * a, 2 * a + 1], axis=1).ravel(), a


def _slave(Z, which: np.ndarray, BT: np.ndarray, m: int) -> None:
    """The anchor rows of the pairs ``which`` (pa,) bool set to their slaved value δw = δu_T = B_T δq."""
    a = np.flatnonzero(which)
    if len(a):
        rows = 2 * m + np.stack([2 * a, 2 * a + 1], axis=1).ravel()
        Z[rows] = BT[a].reshape(2 * len(a), m) @ Z[:m]


def _law_blocks(K, Bp, tan: dict, sel: np.ndarray) -> dict:
    """The parts of :func:`_step_operators` on the pieces ``sel`` that do not depend on the step:
    ``KB`` (n, m, m) N/m = K + BᵀK_u B; of the anchors, the entries (piece, pair) that push (K_w ≠ 0:
    in contact; a separated pair adds nothing, 80 % of them at 128 pairs) in order of piece, piece
    k's in [``wptr[k]``, ``wptr[k+1]``), their state rows ``wrows`` (:func:`_index_rows`), pieces
    ``kf`` and force on δq ``Lf`` (e, m, 2) N/m = B_aᵀK_w; and the entries whose 2×2 block must be
    solved (``ke``, ``ae``): not stuck (a stuck pair's E_w = I, A_w = A_u = 0 give D = I, P = 0
    exactly) and in contact or pushing (a separated pair's rows are slaved), with their ``Ew``,
    ``Aw`` (1/s), ``AuB`` = A_u B_a (e, 2, m), ``slip`` (in contact: their rows are carried), and
    ``hit`` those that push, at ``epos`` among the pushing ones. Only the nonzero law is
    multiplied out: per pair the components of K_u that are nonzero somewhere (memory: the
    diagonal), K_w where ≠ 0."""
    m = K.shape[0]
    Kp = tan["Kp"][sel]
    n, p = Kp.shape[:2]
    comp = np.flatnonzero(np.any(Kp != 0, axis=(0, 1)))          # of the 3×3 components
    ci, cj = np.divmod(comp, 3)
    W = (Bp[:, ci, :, None] * Bp[:, cj, None, :]).reshape(p * len(comp), m * m)     # B_iᵀ B_j per pair
    KB = K + (Kp.reshape(n, p, 9)[:, :, comp].reshape(n, -1) @ W).reshape(n, m, m)
    idx = tan.get("idx", np.zeros(0, int))
    pa = len(idx)
    out = {"KB": KB, "pa": pa}
    if not pa:
        return out
    Ba = Bp[idx]                                                             # (pa, 3, m)
    Kw, Ew, Aw, Au = (tan[k][sel] for k in ("Kw", "Ew", "Aw", "Au"))
    push = np.any(Kw != 0, axis=(2, 3))
    wptr, wrows, af = _index_rows(push, m)
    kf = np.repeat(np.arange(n), np.diff(wptr))
    contact = tan["contact"][sel]
    ke, ae = np.nonzero(~tan["stick"][sel] & (contact | push))
    out.update(wptr=wptr, wrows=wrows, kf=kf, Lf=np.matmul(Ba[af].transpose(0, 2, 1), Kw[kf, af]),
               ke=ke, ae=ae, Ew=Ew[ke, ae], Aw=Aw[ke, ae], AuB=np.matmul(Au[ke, ae], Ba[ae]),
               slip=contact[ke, ae], hit=push[ke, ae], epos=np.searchsorted(kf * pa + af, ke * pa + ae))
    return out


def _step_operators(M, C, law: dict, hs: np.ndarray) -> dict:
    """One backward-Euler step on the pieces of ``law`` (:func:`_law_blocks`; steps ``hs`` s), solved
    for the new state z₁ = [q₁, v₁, w₁] from z₀ through the anchors' 2×2 blocks: E z₁ − hs A z₁ = E z₀
    reads q₁ = q₀ + hs v₁, and per active pair a (its δu = B_a q) ``G_a w₁ = E_w w₀ + hs A_u B_a q₁``
    with G_a = E_w − hs A_w (2×2: I in stick, hs I when separated, (1 + hs κ) nnᵀ + hs ttᵀ in slip —
    never singular), so w₁ = D w₀ + P q₁ with D = G⁻¹E_w, P = hs G⁻¹A_u B_a; the velocity rows are
    then the m×m system ``S v₁ = M v₀ − hs K_eff q₀ − hs L D w₀``, S = M + hs C + hs² K_eff,
    K_eff = K + BᵀK_u B + L P, L = BᵀK_w. Only the pairs not stuck are solved (a stuck pair's
    D = I, P = 0). Per piece: ``Av`` (m, 2m + 2c) with v₁ = Av [q₀, v₀, w₀ of the c pairs that
    push] (:func:`_law_blocks`' ``wptr``, ``wrows``: L is zero for the others, which are packed
    out); of the pairs in slip (a separated one's rows are slaved, :func:`_propagate`) ``ptr``
    (n+1,), ``rows`` (2e,), ``D`` (e, 2, 2), ``P`` (2e, m), piece k's entries e ∈ [ptr[k], ptr[k+1])
    (:func:`_index_rows`); ``hs``."""
    m = M.shape[0]
    npc = len(hs)
    hs3 = hs[:, None, None]
    Keff, pa = law["KB"], law["pa"]
    L = np.zeros((npc, m, 0))
    ops = {"hs": hs, "ptr": np.zeros(npc + 1, int)}
    if pa:
        ke, ae, hit = law["ke"], law["ae"], law["hit"]
        he = hs[ke, None, None]
        Gi = np.linalg.inv(law["Ew"] - he * law["Aw"])
        D, P = np.matmul(Gi, law["Ew"]), he * np.matmul(Gi, law["AuB"])
        epos = law["epos"][hit]
        Le = law["Lf"][epos]
        Keff = Keff.copy()
        kh = ke[hit]                                                 # sorted: the pieces' sums of L P
        first = np.flatnonzero(np.diff(kh, prepend=-1))
        if len(first):
            Keff[kh[first]] += np.add.reduceat(np.matmul(Le, P[hit]), first, axis=0)   # + L P of the pairs solved
        LD = law["Lf"].copy()
        LD[epos] = np.matmul(Le, D[hit])                             # L D (a stuck pair's D = I)
        wptr, kf = law["wptr"], law["kf"]
        width = int(np.diff(wptr).max())
        Lc = np.zeros((npc, m, width, 2))
        Lc[kf, :, np.arange(len(kf)) - wptr[kf]] = LD               # packed: piece k's pushing pairs first
        L = Lc.reshape(npc, m, 2 * width)
        s = law["slip"]
        ptr, rows, _ = _index_rows(_entries_mask(ke[s], ae[s], npc, pa), m)
        ops.update(ptr=ptr, rows=rows, D=D[s], P=P[s].reshape(-1, m), wptr=wptr, wrows=law["wrows"])
    # S⁻¹[K_eff, M, L D]: the inverse of the small S then a product, not a solve with its 2m + 2c
    # right-hand sides (numpy's stacked solve took 9× as long at 128 pairs, m = 7)
    X = np.linalg.inv(M + hs3 * C + hs3 ** 2 * Keff) @ np.concatenate([Keff, np.broadcast_to(M, Keff.shape), L], axis=2)
    ops["Av"] = np.concatenate([-hs3 * X[:, :, :m], X[:, :, m:2 * m], -hs3 * X[:, :, 2 * m:]], axis=2)
    return ops


def _entries_mask(k: np.ndarray, a: np.ndarray, n: int, pa: int) -> np.ndarray:
    """(n, pa) bool, True at the entries (k, a)."""
    mask = np.zeros((n, pa), bool)
    mask[k, a] = True
    return mask


def _step(Z, v1, ops: dict, k: int, m: int) -> None:
    """One backward-Euler step of piece k (:func:`_step_operators`) applied to the columns of Z, in
    place (``v1`` (m, ncol) scratch): the rows of the anchors that slip in the piece are updated, a
    stuck pair's stay (D = I, P = 0) and a separated one's are slaved (:func:`_propagate`)."""
    w = ops["wrows"][2 * ops["wptr"][k]:2 * ops["wptr"][k + 1]] if "wptr" in ops else _NO_ROWS
    np.matmul(ops["Av"][k][:, :2 * m + len(w)], np.concatenate([Z[:2 * m], Z[w]]), out=v1)   # from the old state
    Z[:m] += ops["hs"][k] * v1                          # q₁
    Z[m:2 * m] = v1
    lo, hi = ops["ptr"][k], ops["ptr"][k + 1]
    if hi > lo:
        rows = ops["rows"][2 * lo:2 * hi]
        w0 = Z[rows]
        Z[rows] = (ops["D"][lo:hi] @ w0.reshape(-1, 2, Z.shape[1])).reshape(len(rows), -1) + ops["P"][2 * lo:2 * hi] @ Z[:m]


def _pieces_loops(Z, Av, hs, ptr, rows, D, P, tptr, trows, slaved, wptr, wrows, sub, m):
    """The pieces of one chunk of :func:`_propagate`, ``sub`` steps each, as loops for numba:
    per piece the anchors that touch again set to their slaved value (``tptr``, ``trows``,
    ``slaved``: :func:`_index_rows` of the chunk), then :func:`_step` ``sub`` times, ``Av``'s
    anchor columns those of the pairs that push (``wptr``, ``wrows``: :func:`_step_operators`). A Python
    call per step costs more than the step (7 × (14 + 2·5) by 18 columns at 128 pairs). The
    product ``Av[j] @ Z`` is a loop too, compiled with fastmath so that its sums vectorise:
    numba's ``np.dot`` took 5.3 of the 6.3 s of its compilation, which a fresh checkout (CI) pays
    once a process. The ~99 000 steps of a 50-point stability at 128 pairs take 0.11 s (one
    thread, 2026-11-29)."""
    nc = Z.shape[1]
    v1 = np.empty((m, nc))
    sums = np.empty(nc)
    Zw = np.empty((Av.shape[2], nc))
    for j in range(Av.shape[0]):
        for r in range(2 * tptr[j], 2 * tptr[j + 1]):
            row = trows[r]
            for c in range(nc):
                acc = 0.0
                for i in range(m):
                    acc += slaved[r, i] * Z[i, c]
                Z[row, c] = acc
        for _ in range(sub):
            # the pushing anchors' rows gathered first, and the columns innermost into a local sum:
            # contiguous, they vectorise (twice as fast as summing into v1 row by row)
            nw = 2 * (wptr[j + 1] - wptr[j])
            for r in range(nw):
                row = wrows[2 * wptr[j] + r]
                for c in range(nc):
                    Zw[r, c] = Z[row, c]
            for i in range(m):
                for c in range(nc):
                    sums[c] = 0.0
                for q in range(2 * m):
                    x = Av[j, i, q]
                    for c in range(nc):
                        sums[c] += x * Z[q, c]
                for r in range(nw):
                    x = Av[j, i, 2 * m + r]
                    for c in range(nc):
                        sums[c] += x * Zw[r, c]
                for c in range(nc):
                    v1[i, c] = sums[c]
            for i in range(m):
                for c in range(nc):
                    Z[i, c] += hs[j] * v1[i, c]
                    Z[m + i, c] = v1[i, c]
            for e in range(ptr[j], ptr[j + 1]):
                a, b = rows[2 * e], rows[2 * e + 1]
                for c in range(nc):
                    wa, wb = Z[a, c], Z[b, c]
                    Z[a, c] = D[e, 0, 0] * wa + D[e, 0, 1] * wb
                    Z[b, c] = D[e, 1, 0] * wa + D[e, 1, 1] * wb
                for i in range(m):
                    xa, xb = P[2 * e, i], P[2 * e + 1, i]
                    for c in range(nc):
                        Z[a, c] += xa * Z[i, c]
                        Z[b, c] += xb * Z[i, c]


#: the compiled :func:`_pieces_loops`, or None: :func:`_step` a call a step (the test oracle)
_pieces_numba = compiled(_pieces_loops, fastmath=True)


_NO_ROWS, _NO_D = np.zeros(0, np.int64), np.zeros((0, 2, 2))
