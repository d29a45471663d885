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

from reduction.condense import rayleigh
from reduction.reduced import ReducedModel

__all__ = ["with_interface_layer"]

def layer_stiffness(area, kn: float, kt: float) -> np.ndarray:
    """(3p,) spring of each relative DOF [N/m], pair-major [n, t1, t2]: k·A_i, 0 where k = 0 (rigid)."""
    A = np.asarray(area, float)
    return np.column_stack([kn * A, kt * A, kt * A]).ravel()


def _layered(model: ReducedModel, kn: float, kt: float) -> ReducedModel:
    m, B = model.size, model.B
    k = layer_stiffness(model.area, kn, kt)
    soft = np.flatnonzero(k > 0)                       # the layered relative DOFs; the others stay rigid
    ns = soft.size
    ks, L = k[soft], B[soft]
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
    Bn = np.zeros((B.shape[0], m + ns))
    rigid = np.setdiff1d(np.arange(B.shape[0]), soft)
    Bn[rigid, :m] = B[rigid]
    Bn[soft, m + np.arange(ns)] = 1.0
    zero = np.zeros(ns)
    info = dict(model.info, interface_layer={"stiffness_n_per_m3": kn, "stiffness_t_per_m3": kt,
                                             "layer_dofs": int(ns), "damping_beta": beta})
    return replace(model, M=M, K=K, C=C, B=Bn, f_static=np.r_[model.f_static, zero],
                   f_harmonic=np.r_[model.f_harmonic, zero], O=np.hstack([model.O, np.zeros((model.O.shape[0], ns))]),
                   info=info)


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
