"""Reduced against full: eigenfrequencies, MAC and linear FRFs in the two contact limits.

* **tied** — blade contact DOFs follow their disk partners. Full model via
  :func:`reduction.constraints.constraint_map` (``tied=True``); reduced model
  with the constraint ``B q = 0`` (q = N y, N an orthonormal null-space
  basis of B).
* **free** — no contact at all (λ = 0). Full: the clamped model; reduced: q
  unconstrained. The blade then floats: its rigid-body modes (ω ≈ 0) are
  skipped — any mode below ``RIGID_FRACTION`` × the highest frequency
  computed — and their number is reported.

Errors: relative frequency error per mode, MAC of each full mode with the
reduced mode of the same rank (reduced modes expanded to all DOFs with the
basis), and for the FRF at the observed DOFs over a band around the first
tied mode ``max_ω |H_red − H_full| / max_ω |H_full|`` (relative to the
peak, so that anti-resonances do not dominate). Reduced FRFs go through
:mod:`workflow.engine.condense` (free: ``Z_r U_r = F_r``; tied: ``U_r = 0``) and
:func:`~workflow.engine.condense.recover`, i.e. the path the nonlinear solver uses.

Full FRFs: a complex sparse LU per frequency (scipy ``splu``) for small
models; above ``DIRECT_LIMIT`` DOFs a complex LU per frequency is far too
slow (≈ 40 s each at 50k DOFs), so all frequencies share one real MUMPS
factor of ``K − σM`` and one growing subspace: Galerkin solutions, enriched
with the preconditioned residuals ``(K − σM)⁻¹ r(ω)`` of the frequencies not
yet converged, until every true residual ``‖D(ω)u − f‖ ≤ tol‖f‖``. That is
an iterative solver of the full equations (checked against ``splu`` in the
tests), not a reduction.

Frequencies in Hz at the interface, rad/s inside.
"""
from __future__ import annotations

import csv
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from reduction.bundle import Bundle
from workflow.engine.condense import condense, recover, relative_coordinates
from reduction.constraints import constrain, constraint_map
from reduction.reduce import Basis, reduce_with_basis
from workflow.engine.model import ReducedModel
from workflow.errors import SolverError

RIGID_FRACTION = 1e-3  # a mode below this fraction of the highest computed frequency is a rigid-body mode
DIRECT_LIMIT = 5000  # DOFs up to which full FRFs use a complex splu per frequency
FRF_TOL = 1e-9  # relative residual of the iterative full FRF
BAND = 0.1  # FRF band: f1 × [1 − BAND, 1 + BAND]
CHECK_DAMPING = 1e-3  # modal ratio at f1 used for the FRFs when the bundle has C = 0


# ---------------------------------------------------------------- modes


def mac(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Modal assurance criterion of matching columns of A and B (k,), in [0, 1]."""
    num = np.abs(np.einsum("ij,ij->j", A.conj(), B)) ** 2
    den = np.einsum("ij,ij->j", A.conj(), A).real * np.einsum("ij,ij->j", B.conj(), B).real
    return num / den


def full_modes(bundle: Bundle, n: int, tied: bool, rigid_fraction: float = RIGID_FRACTION):
    """Lowest ``n`` elastic modes of the full model: ``(f_hz, Phi (n_dofs, n), n_rigid)``.

    SLEPc shift-invert with a small negative shift, so a floating blade is no
    problem; when free, 6 extra modes are asked for and the rigid ones dropped.
    """
    from reduction.modes import modes

    extra = 0 if tied else 8
    f, _, Phi = modes(bundle, n + extra, tied=tied)
    rigid = f < rigid_fraction * f.max() if not tied else np.zeros(f.size, bool)
    keep = np.flatnonzero(~rigid)[:n]
    return f[keep], Phi[:, keep], int(rigid.sum())


def reduced_modes(model: ReducedModel, tied: bool, n: int | None = None, rigid_fraction: float = RIGID_FRACTION):
    """Elastic modes of the reduced model: ``(f_hz, Q (m, k), n_rigid)`` (dense, all of them).

    Tied: ``B q = 0`` by q = N y with N = null(B).
    """
    if tied:
        N = sla.null_space(model.B) if model.B.shape[0] else np.eye(model.size)
        w2, Y = sla.eigh(N.T @ model.K @ N, N.T @ model.M @ N)
        Q = N @ Y
    else:
        w2, Q = sla.eigh(model.K, model.M)
    f = np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi)
    top = f[min(f.size, (n or f.size) + 8) - 1]  # as in full_modes: the highest of n + 8 computed
    rigid = f < rigid_fraction * top if not tied else np.zeros(f.size, bool)
    keep = np.flatnonzero(~rigid)
    if n is not None:
        keep = keep[:n]
    return f[keep], Q[:, keep], int(rigid.sum())


# ---------------------------------------------------------------- FRFs


def band(f1_hz: float, points: int, width: float = BAND) -> np.ndarray:
    """Angular frequencies [rad/s] of ``points`` values over f1 × [1 − width, 1 + width]."""
    return 2 * np.pi * np.linspace((1 - width) * f1_hz, (1 + width) * f1_hz, points)


def check_beta(bundle: Bundle, f1_hz: float) -> float:
    """Extra stiffness-proportional damping β [s] for the FRF check: 0 unless C = 0."""
    return 0.0 if bundle.C.nnz and np.abs(bundle.C.data).max() > 0 else 2 * CHECK_DAMPING / (2 * np.pi * f1_hz)


def full_frf(bundle: Bundle, omegas: np.ndarray, tied: bool, beta: float = 0.0, method: str = "auto",
             tol: float = FRF_TOL, stats: dict | None = None) -> np.ndarray:
    """Observed response (n_ω, n_obs) complex [m/N·N] of the full model to the harmonic load.

    ``D(ω) = K − ω²M + iω(C + βK)`` on the clamped (and, if ``tied``, bonded)
    DOFs. ``method``: "direct" (complex splu per ω), "iterative" (see module
    doc) or "auto" (direct up to ``DIRECT_LIMIT`` DOFs).
    """
    T = constraint_map(bundle, tied=tied)
    K, M, C = (constrain(A, T) for A in (bundle.K, bundle.M, bundle.C))
    if beta:
        C = (C + beta * K).tocsr()
    f = T.T @ bundle.loads.harmonic
    Obs = sp.csr_matrix(T)[np.asarray(bundle.loads.observe, dtype=np.int64)]
    if method == "auto":
        method = "direct" if K.shape[0] <= DIRECT_LIMIT else "iterative"
    if method == "direct":
        X = np.empty((K.shape[0], len(omegas)), dtype=complex)
        for i, w in enumerate(omegas):
            X[:, i] = spla.splu(sp.csc_matrix(K - w * w * M + 1j * w * C)).solve(f.astype(complex))
    elif method == "iterative":
        X = _frf_subspace(K, M, C, f, np.asarray(omegas), tol, stats)
    else:
        raise ValueError(f"unknown FRF method {method!r}")
    return (Obs @ X).T


def _frf_subspace(K, M, C, f, omegas, tol, stats=None, max_iter=60):
    """Solutions of ``D(ω_k) x_k = f`` for all ω_k from one shared, growing subspace."""
    from reduction.craig_bampton import SparseFactor, _Columns, _m_orthonormalize

    wc = 0.5 * (omegas.min() + omegas.max())
    P = SparseFactor((K + wc * wc * M).tocsr())  # σ = −ω_c²: regular even with a floating blade
    n = K.shape[0]
    U, KU, MU, CU = (_Columns(n, 64) for _ in range(4))
    W, MW = _m_orthonormalize(P.solve(f)[:, None], M)
    fn = np.linalg.norm(f)
    todo = np.arange(omegas.size)
    X = np.zeros((n, omegas.size), dtype=complex)
    for it in range(max_iter):
        U.append(W), MU.append(MW), KU.append(K @ W), CU.append(C @ W)
        Kr, Mr, Cr, fr = U.view.T @ KU.view, U.view.T @ MU.view, U.view.T @ CU.view, U.view.T @ f
        R = []
        for k in todo:
            w = omegas[k]
            y = np.linalg.solve(Kr - w * w * Mr + 1j * w * Cr, fr)
            r = KU.view @ y - w * w * (MU.view @ y) + 1j * w * (CU.view @ y) - f
            X[:, k] = U.view @ y
            R.append(None if np.linalg.norm(r) <= tol * fn else r)
        left = [i for i, r in enumerate(R) if r is not None]
        if not left:
            if stats is not None:
                stats.update(subspace=int(U.k), iterations=it + 1)
            P.destroy()
            return X
        Rm = np.column_stack([R[i] for i in left])
        todo = todo[left]
        W, MW = _m_orthonormalize(P.solve(np.hstack([Rm.real, Rm.imag])), M, U.view, MU.view)
        if W.shape[1] == 0:
            break
    P.destroy()
    raise SolverError(f"full FRF: {todo.size} frequencies not converged to {tol:g} after {max_iter} enrichments")


def reduced_frf(model: ReducedModel, omegas: np.ndarray, tied: bool, beta: float = 0.0) -> np.ndarray:
    """Observed response (n_ω, n_obs) of the reduced model through condensation (eq. 3).

    Free: λ = 0, so ``Z_r U_r = F_r``; tied: ``U_r = 0``. Then ``recover``.
    """
    if beta:
        model = ReducedModel(**{**model.__dict__, "C": model.C + beta * model.K})
    rc = relative_coordinates(model)
    out = np.empty((len(omegas), model.O.shape[0]), dtype=complex)
    r = 3 * model.n_pairs
    for i, w in enumerate(omegas):
        Ur = np.zeros((2, r), dtype=complex)
        if not tied:
            cond = condense(rc, w, nh=1)
            Ur[1] = np.linalg.solve(cond.Zr[1], cond.Fr[1])
        out[i] = recover(rc, w, Ur)[1]
    return out


def frf_error(H: np.ndarray, H_ref: np.ndarray) -> float:
    """``max |H − H_ref| / max |H_ref|`` over frequencies and observed DOFs."""
    return float(np.abs(H - H_ref).max() / np.abs(H_ref).max())


# ---------------------------------------------------------------- study


@dataclass
class Reference:
    """Full-model results, computed once for all reductions compared with them."""

    n_check: int
    tied_hz: np.ndarray
    tied_phi: np.ndarray
    free_hz: np.ndarray
    free_phi: np.ndarray
    free_rigid: int
    omegas: np.ndarray  # FRF band [rad/s]
    beta: float  # extra damping of the FRF check [s]
    frf_tied: np.ndarray
    frf_free: np.ndarray
    seconds: dict = field(default_factory=dict)


def reference(bundle: Bundle, n_check: int = 10, frf_points: int = 40, log=None) -> Reference:
    """Full tied and free modes and FRFs over the band around the first tied mode."""
    sec = {}
    t0 = time.perf_counter()
    tf, tphi, _ = full_modes(bundle, n_check, tied=True)
    ff, fphi, rigid = full_modes(bundle, n_check, tied=False)
    sec["full_modes"] = time.perf_counter() - t0
    _say(log, f"full tied modes [Hz]: {', '.join(f'{v:.1f}' for v in tf)}; free: {rigid} rigid-body modes skipped")
    omegas = band(tf[0], frf_points)
    beta = check_beta(bundle, tf[0])
    t0 = time.perf_counter()
    H_t = full_frf(bundle, omegas, tied=True, beta=beta)
    H_f = full_frf(bundle, omegas, tied=False, beta=beta)
    sec["full_frf"] = time.perf_counter() - t0
    return Reference(n_check, tf, tphi, ff, fphi, rigid, omegas, beta, H_t, H_f, sec)


def evaluate(model: ReducedModel, ref: Reference, basis: Basis | None = None) -> dict:
    """Errors of one reduced model against ``ref`` (nested dict, JSON-ready).

    MAC needs the basis (reduced modes expanded to all DOFs); without it the
    ``min_mac`` entries are None.
    """
    out = {"modes": int(model.info.get("modes", -1)), "boundary_dofs": int(model.info.get("boundary_dofs", -1)),
           "size": int(model.size)}
    for tied, key, f_ref, phi_ref, H_ref in ((True, "tied", ref.tied_hz, ref.tied_phi, ref.frf_tied),
                                             (False, "free", ref.free_hz, ref.free_phi, ref.frf_free)):
        f, Q, rigid = reduced_modes(model, tied, ref.n_check)
        k = min(f.size, f_ref.size)
        err = (f[:k] - f_ref[:k]) / f_ref[:k]
        row = {"full_hz": f_ref[:k].tolist(), "reduced_hz": f[:k].tolist(), "rel_freq_error": err.tolist(),
               "max_rel_freq_error": float(np.abs(err).max()), "rigid_skipped": int(rigid)}
        if basis is not None:
            m = mac(phi_ref[:, :k], basis.expand(Q[:, :k]))
            row["mac"] = m.tolist()
            row["min_mac"] = float(m.min())
        else:
            row["mac"], row["min_mac"] = None, None
        H = reduced_frf(model, ref.omegas, tied, ref.beta)
        row["frf_max_rel_error"] = frf_error(H, H_ref)
        out[key] = row
    out["frf_max_rel_error"] = max(out["tied"]["frf_max_rel_error"], out["free"]["frf_max_rel_error"])
    return out


def convergence_study(bundle: Bundle, counts, ref: Reference, log=None, **reduce_kwargs) -> list[dict]:
    """Reduce with each fixed-interface mode count, time it, evaluate it against ``ref``."""
    rows = []
    for count in sorted(set(int(c) for c in counts)):
        t0 = time.perf_counter()
        model, basis = reduce_with_basis(bundle, count, **reduce_kwargs)
        seconds = time.perf_counter() - t0
        row = evaluate(model, ref, basis)
        row["seconds"] = seconds
        row["seconds_detail"] = model.info["seconds"]
        rows.append(row)
        _say(log, f"{count} modes: {seconds:.2f} s, tied max |Δf/f| {row['tied']['max_rel_freq_error']:.2e}, "
                  f"min MAC {row['tied']['min_mac']:.6f}, FRF {row['frf_max_rel_error']:.2e}")
    return rows


COLUMNS = ("modes", "size", "seconds", "tied_max_rel_freq_error", "tied_min_mac", "free_max_rel_freq_error",
           "free_min_mac", "tied_frf_max_rel_error", "free_frf_max_rel_error")


def flat_row(row: dict) -> dict:
    """One CSV row of the convergence table."""
    return {"modes": row["modes"], "size": row["size"], "seconds": row["seconds"],
            "tied_max_rel_freq_error": row["tied"]["max_rel_freq_error"], "tied_min_mac": row["tied"]["min_mac"],
            "free_max_rel_freq_error": row["free"]["max_rel_freq_error"], "free_min_mac": row["free"]["min_mac"],
            "tied_frf_max_rel_error": row["tied"]["frf_max_rel_error"],
            "free_frf_max_rel_error": row["free"]["frf_max_rel_error"]}


def write_table(rows: list[dict], path) -> None:
    """Convergence table as CSV (one row per mode count)."""
    from workflow.io import atomic_path

    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in flat_row(row).items()})


def write_modes_table(row: dict, path) -> None:
    """Per-mode comparison (tied and free) of one reduced model as CSV."""
    from workflow.io import write_text

    lines = ["limit,mode,f_full_hz,f_reduced_hz,rel_error,mac"]
    for key in ("tied", "free"):
        r = row[key]
        for i, (a, b, e) in enumerate(zip(r["full_hz"], r["reduced_hz"], r["rel_freq_error"])):
            m = "" if r["mac"] is None else f"{r['mac'][i]:.9f}"
            lines.append(f"{key},{i + 1},{a:.9g},{b:.9g},{e:.3e},{m}")
    write_text(path, "\n".join(lines) + "\n")


def plot_convergence(rows: list[dict], path) -> None:
    """Errors against reduction wall time, one marker per mode count (PNG, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow.io import atomic_path

    t = np.array([r["seconds"] for r in rows])
    series = [("tied max |Δf/f|", [r["tied"]["max_rel_freq_error"] for r in rows], "o-"),
              ("free max |Δf/f|", [r["free"]["max_rel_freq_error"] for r in rows], "s-"),
              ("tied 1 − min MAC", [1 - r["tied"]["min_mac"] for r in rows], "^-"),
              ("FRF tied", [r["tied"]["frf_max_rel_error"] for r in rows], "v--"),
              ("FRF free", [r["free"]["frf_max_rel_error"] for r in rows], "d--")]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, y, style in series:
        ax.semilogy(t, np.maximum(np.abs(y), 1e-16), style, label=label)
    for r, x in zip(rows, t):
        ax.annotate(str(r["modes"]), (x, r["tied"]["max_rel_freq_error"] or 1e-16), textcoords="offset points",
                    xytext=(4, 4), fontsize=8)
    ax.set_xlabel("reduction wall time [s]")
    ax.set_ylabel("relative error")
    ax.set_title("Craig–Bampton: error against cost (labels: fixed-interface modes)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)


def _say(log, msg):
    if log is not None:
        log.info(msg)
