"""Measures of a worn state that can converge with the contact mesh (issue 48 item 3).

The node-wise maximum depth is the most mesh-sensitive number a wear study gives: it is one
pair's value of a field whose pattern the node-wise Archard law (eq. 21) does not regularise.
These are integrals over a flank, or the field seen at a physical length ℓ, which a finer
contact mesh approximates better rather than differently. All take arrays and return numbers
(SI); a pair is one node pair with its tributary area, ``flank`` 0 intrados, 1 extrados.
"""
from __future__ import annotations

import numpy as np

#: a pair belongs to the wear scar when its depth is at least this fraction of the flank's
#: largest (the scar's edge: 5 % is where a measured fretting-scar profile meets its noise)
SCAR_FRACTION = 0.05

#: the flank codes of ``ReducedModel.flank``
FLANK_NAMES = {0: "intrados", 1: "extrados"}


def _flanks(flank) -> list[int]:
    return sorted(int(f) for f in np.unique(np.asarray(flank)))


def worn_volume(W, area, flank) -> dict:
    """Worn volume per flank, {flank: Σ W_i A_i} [m³]: W (p,) the pairs' wear depth [m] (blade
    and disk together), A (p,) their tributary areas [m²]."""
    W, A, fl = np.asarray(W, float), np.asarray(area, float), np.asarray(flank)
    return {f: float(np.sum(W[fl == f] * A[fl == f])) for f in _flanks(fl)}


def filter_matrix(position, area, ell: float) -> np.ndarray:
    """(p, p) row-stochastic Gaussian filter at length ``ell`` [m] with the tributary areas as
    weights: row i = A_j exp(−|x_i − x_j|²/(2ℓ²)) / Σ_j (·) — the average of a field over a
    disk of radius ~ℓ around pair i, whatever the mesh. ℓ = 0: the identity."""
    P, A = np.asarray(position, float), np.asarray(area, float)
    if ell <= 0:
        return np.eye(len(A))
    d2 = np.sum((P[:, None, :] - P[None, :, :]) ** 2, axis=-1)
    G = A[None, :] * np.exp(-d2 / (2.0 * ell * ell))
    return G / G.sum(axis=1, keepdims=True)


def filtered_profile(W, position, area, flank, ell: float) -> np.ndarray:
    """W (p,) [m] averaged at length ``ell`` [m] over its own flank (the flanks do not mix)."""
    W, fl = np.asarray(W, float), np.asarray(flank)
    out = np.empty_like(W)
    for f in _flanks(fl):
        m = fl == f
        out[m] = filter_matrix(np.asarray(position)[m], np.asarray(area)[m], ell) @ W[m]
    return out


def profile_l2(W, area, flank) -> dict:
    """Area-weighted RMS depth per flank, {flank: √(Σ A_i W_i² / Σ A_i)} [m] — the L2 norm of
    the profile over the flank divided by √area, so meshes of one flank compare."""
    W, A, fl = np.asarray(W, float), np.asarray(area, float), np.asarray(flank)
    return {f: float(np.sqrt(np.sum(A[fl == f] * W[fl == f] ** 2) / np.sum(A[fl == f]))) for f in _flanks(fl)}


def scar(W, position, area, flank, fraction: float = SCAR_FRACTION) -> dict:
    """The wear scar per flank: pairs with W ≥ ``fraction`` × the largest depth of the whole
    interface (so a flank that barely wears has no scar, not one scaled to its own round-off).
    {flank: {"area_m2": Σ A over them, "width_m": their extent along the flank's long axis
    (the principal direction of the flank's pair positions)}}; a flank without one has 0 and 0."""
    W, A, fl, P = np.asarray(W, float), np.asarray(area, float), np.asarray(flank), np.asarray(position, float)
    top = W.max(initial=0.0)
    out = {}
    for f in _flanks(fl):
        m = fl == f
        if top <= 0 or W[m].max(initial=0.0) < fraction * top:
            out[f] = {"area_m2": 0.0, "width_m": 0.0}
            continue
        x = P[m] - P[m].mean(axis=0)
        axis = np.linalg.svd(x, full_matrices=False)[2][0] if len(x) > 1 else np.zeros(P.shape[1])
        s = x @ axis
        on = W[m] >= fraction * top
        out[f] = {"area_m2": float(A[m][on].sum()), "width_m": float(np.ptp(s[on])) if on.sum() > 1 else 0.0}
    return out


def wear_measures(W, position, area, flank, ell: float) -> dict:
    """Every measure of one worn state, keyed by flank name ("intrados", "extrados") where the
    flank labels are 0/1: worn volume [m³], the ℓ-filtered profile's RMS depth and maximum [m]
    (ℓ [m]; 0: the node-wise profile), scar area [m²] and width [m], and the node-wise maximum
    depth [m] — the mesh-sensitive number, reported as such."""
    name = FLANK_NAMES
    vol = worn_volume(W, area, flank)
    Wf = filtered_profile(W, position, area, flank, ell)
    l2 = profile_l2(Wf, area, flank)
    sc = scar(W, position, area, flank)
    fl = np.asarray(flank)
    out = {}
    for f in vol:
        out[name.get(f, str(f))] = {"worn_volume_m3": vol[f], "profile_l2_m": l2[f],
                                    "filtered_max_m": float(Wf[fl == f].max()), "scar_area_m2": sc[f]["area_m2"],
                                    "scar_width_m": sc[f]["width_m"], "max_wear_m": float(np.asarray(W)[fl == f].max())}
    return {"length_m": float(ell), "flanks": out,
            "worn_volume_m3": float(sum(vol.values())), "max_wear_m": float(np.max(W)) if len(W) else 0.0}
