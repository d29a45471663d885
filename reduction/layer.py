"""An elastic interface layer: the contact's own stiffness per unit area, in series with the structure.

Rough surfaces in contact deform at their asperities before the bodies do. Blade-root and damper
models carry this as a normal and a tangential contact stiffness per unit area, k_n and k_t
[N/m³], measured on flat-on-flat rigs (tens to hundreds of N/(µm·mm²), 1e13–1e14 N/m³ and more).
Each pair i gets springs k_n·A_i and k_t·A_i (A_i its tributary area [m²]) between the structure's
relative displacement B q and an interface displacement s, and the DLFT contact law acts on s:
a stuck pair still moves tangentially by λ_T/(k_t A_i), a closed one interpenetrates by
λ_N/(k_n A_i). With k → ∞ the layer vanishes and the contact is the paper's rigid one.

The layer is massless, so it adds coordinates to the reduced model, not to the physics of the
structure: the new model's relative DOFs are s (``B`` selects them) and the structure's B q becomes
one of its internal coordinates. Everything downstream (condensation, tied modes, recovery of the
observed DOFs) takes it unchanged. Damping: where C = αM + βK, the layer gets β k as well, which
keeps the model Rayleigh (the condensation's tied-mode path); otherwise it has none.

The layer regularises the line load a sharp bearing edge carries: its pressure spreads over about
E*/k_n (E* the contact modulus), so the static contact pressure converges with the contact mesh
once the mesh resolves that length (docs/contact-layout.md).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from workflow.engine.condense import rayleigh
from workflow.engine.model import ReducedModel

__all__ = ["with_interface_layer", "with_sampled_layer", "sample_points"]

def layer_stiffness(area, kn: float, kt: float) -> np.ndarray:
    """(3p,) spring of each relative DOF [N/m], pair-major [n, t1, t2]: k·A_i, 0 where k = 0 (rigid)."""
    A = np.asarray(area, float)
    return np.column_stack([kn * A, kt * A, kt * A]).ravel()


def _springs(model: ReducedModel, L: np.ndarray, ks: np.ndarray):
    """(M, K, C, β) of ``model`` with springs ks (ns,) [N/m] between L q (L (ns, m)) and ns new
    massless coordinates s, appended after q; β the Rayleigh β the springs' damping takes (None:
    no Rayleigh damping, the springs undamped)."""
    m, ns = model.size, ks.size
    ab = rayleigh(model.M, model.K, model.C)
    beta = None if ab is None else ab[1]
    dtype = np.result_type(model.K, model.M, model.C, float)
    K = np.zeros((m + ns, m + ns), dtype)
    K[:m, :m] = model.K + L.T @ (ks[:, None] * L)
    K[:m, m:] = -(L.T * ks)
    K[m:, :m] = -(ks[:, None] * L)
    K[m:, m:] = np.diag(ks)
    M = np.zeros_like(K)
    M[:m, :m] = model.M
    C = np.zeros_like(K)
    C[:m, :m] = model.C
    if beta is not None:
        C += beta * (K - np.pad(model.K, ((0, ns), (0, ns))))
    return M, K, C, beta


def _padded(model: ReducedModel, ns: int) -> dict:
    """The loads and observation of ``model`` on ns more (massless, unloaded, unobserved) coordinates."""
    zero = np.zeros(ns)
    return {"f_static": np.r_[model.f_static, zero], "f_harmonic": np.r_[model.f_harmonic, zero],
            "O": np.hstack([model.O, np.zeros((model.O.shape[0], ns))])}


def _layered(model: ReducedModel, kn: float, kt: float) -> ReducedModel:
    m, B = model.size, model.B
    k = layer_stiffness(model.area, kn, kt)
    soft = np.flatnonzero(k > 0)                       # the layered relative DOFs; the others stay rigid
    ns = soft.size
    M, K, C, beta = _springs(model, B[soft], k[soft])
    Bn = np.zeros((B.shape[0], m + ns))
    rigid = np.setdiff1d(np.arange(B.shape[0]), soft)
    Bn[rigid, :m] = B[rigid]
    Bn[soft, m + np.arange(ns)] = 1.0
    info = dict(model.info, interface_layer={"stiffness_n_per_m3": kn, "stiffness_t_per_m3": kt,
                                             "layer_dofs": int(ns), "damping_beta": beta})
    return replace(model, M=M, K=K, C=C, B=Bn, info=info, **_padded(model, ns))


def _subdivided_centroids(s: int) -> np.ndarray:
    """(s², 3) barycentric coordinates of the centroids of a triangle's s² congruent sub-triangles
    (equal areas: the midpoint rule on the triangle split s times along each side)."""
    pts = []
    for i in range(s):
        for j in range(s - i):
            pts.append(((i + 1 / 3) / s, (j + 1 / 3) / s))             # the sub-triangles pointing like it
            if i + j < s - 1:
                pts.append(((i + 2 / 3) / s, (j + 2 / 3) / s))         # and the inverted ones between them
    a = np.array(pts)
    return np.column_stack([1.0 - a.sum(axis=1), a])


def sample_points(position, flank, per_side: int):
    """Points that integrate each flank's contact surface finer than its node pairs.

    Each planar flank's pairs (``position`` (p, 3) [m], ``flank`` (p,)) are triangulated in its plane
    (Delaunay), every triangle split into ``per_side``² equal sub-triangles, and one point put at
    each sub-triangle's centroid. Returns ``(N, area, position, flank)``: N (n, p) the linear
    interpolation from the pairs to the points (rows of barycentric weights), their areas [m²]
    (a triangle's area / per_side² each: Σ = the area the pairs span), positions [m] and flanks."""
    from scipy.spatial import Delaunay

    P, fl = np.asarray(position, float), np.asarray(flank)
    if per_side < 1:
        raise ValueError(f"per_side must be ≥ 1, got {per_side}")
    bary = _subdivided_centroids(int(per_side))
    rows, areas, pos, fls = [], [], [], []
    for f in sorted(np.unique(fl)):
        idx = np.flatnonzero(fl == f)
        x = P[idx] - P[idx].mean(axis=0)
        axes = np.linalg.svd(x, full_matrices=False)[2][:2]
        tri = Delaunay(x @ axes.T).simplices
        corners = P[idx][tri]                                          # (t, 3, 3)
        a = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
        # a regular grid's cocircular corners can leave a sliver along the hull: no area, no point
        keep = a > 1e-9 * a.mean()
        tri, corners, a = tri[keep], corners[keep], a[keep]
        for t in range(len(tri)):
            for b in bary:
                r = np.zeros(len(P))
                r[idx[tri[t]]] = b
                rows.append(r)
                pos.append(b @ corners[t])
            areas.append(np.full(len(bary), a[t] / len(bary)))
            fls.append(np.full(len(bary), f))
    return np.array(rows), np.concatenate(areas), np.array(pos), np.concatenate(fls)


def with_sampled_layer(model: ReducedModel, kn: float, kt: float, per_side: int) -> ReducedModel:
    """``model`` with its interface layer integrated at points finer than its node pairs.

    The layer of :func:`with_interface_layer` lumps each pair's springs and its friction at the
    node: a stick–slip boundary then falls on a row of pairs. Here the springs k_n·a, k_t·a [N/m]
    and the contact law sit at the :func:`sample_points` (a the point's area), each between its own
    interface displacement s and the structure's relative displacement interpolated there,
    N B q — on a linear contact surface the structure's own field, so this is the layer's energy
    integrated by the midpoint rule over ``per_side``² sub-triangles of each surface triangle. The
    points become the model's pairs (gap and friction interpolated from the nodes), so
    condensation, HB, wear and recovery take it unchanged; ``per_side`` = 1 puts one point in each
    triangle. Needs k_n, k_t > 0 [N/m³] and the pairs' local frames alike over each flank (planar
    flanks: their frames come from the one normal). On the fine-solid sector it moves the unworn
    friction power by 0.3–8 % and does not narrow its scatter over contact grids
    (docs/contact-layout.md, "What the worn volume's scatter follows")."""
    kn, kt = float(kn), float(kt)
    if not (kn > 0 and kt > 0 and np.isfinite(kn) and np.isfinite(kt)):
        raise ValueError(f"a sampled layer needs finite k_n, k_t > 0, got k_n = {kn}, k_t = {kt}")
    if getattr(model, "is_cyclic", False):
        raise ValueError("a sampled layer is built on a sector's model, not a cyclic one")
    N, area, pos, fl = sample_points(model.position, model.flank, per_side)
    L = np.kron(N, np.eye(3)) @ model.B                                 # (3n, m): N B q, point-major [n, t1, t2]
    ks = layer_stiffness(area, kn, kt)
    M, K, C, beta = _springs(model, L, ks)
    ns = ks.size
    Bn = np.hstack([np.zeros((ns, model.size)), np.eye(ns)])
    info = {k: v for k, v in model.info.items() if k not in ("tie_pairs",)}   # pair indices of the nodes
    info["interface_layer"] = {"stiffness_n_per_m3": kn, "stiffness_t_per_m3": kt, "layer_dofs": int(ns),
                               "damping_beta": beta, "sample_per_side": int(per_side), "node_pairs": int(len(model.area))}
    mu = None if model.mu is None else N @ np.asarray(model.mu, float)
    return replace(model, M=M, K=K, C=C, B=Bn, area=area, gap=N @ np.asarray(model.gap, float), flank=fl,
                   position=pos, mu=mu, info=info, **_padded(model, ns))


def with_interface_layer(model, kn: float, kt: float):
    """``model`` with interface springs k_n·A_i, k_t·A_i [N/m] in series with every pair (module doc).

    ``kn``, ``kt`` [N/m³] ≥ 0; 0 keeps that direction rigid, and both 0 returns ``model`` itself.
    A :class:`~reduction.cyclic_reduce.CyclicReducedModel` gets the layer on every nodal diameter."""
    kn, kt = float(kn), float(kt)
    if kn < 0 or kt < 0 or not (np.isfinite(kn) and np.isfinite(kt)):
        raise ValueError(f"interface stiffness per unit area must be finite and ≥ 0, got k_n = {kn}, k_t = {kt}")
    if kn == 0 and kt == 0:
        return model
    if getattr(model, "is_cyclic", False):
        return replace(model, models={nd: _layered(m, kn, kt) for nd, m in model.models.items()})
    return _layered(model, kn, kt)
