"""The worn model: the bundle re-assembled on the remapped mesh (contracts §8).

Wear opens the gap; it does not change who touches whom. On the worn mesh
the flank vertices of a pair are W apart and would no longer match, so the
pairs (DOFs, frames, areas) are taken from the unworn mesh, and the worn
bundle's ``gap`` is the new one plus W: the geometry carries the stiffness
of the removed material, the gap its kinematic opening, neither twice
(``workflow/stages/remap.py`` explains it in full).

A cyclic sector (``bundle.cyclic``, docs/cyclic.md) stays one: the wear moves
flank nodes only, so the cut faces — and the cyclic constraint between them —
are the new bundle's (checked, :func:`check_cyclic_faces`); the new and worn
models are then both reduced per nodal diameter
(:func:`reduction.cyclic_reduce.reduce_cyclic`, same EO, harmonics and modes)
and their tied frequencies compared on ND ``EO mod N``, the family the
engine-order excitation (harmonic 1) drives (:func:`new_and_worn`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.errors import GeometryError


def worn_bundle(bundle, mesh, ct, ft, x_worn: np.ndarray, W: np.ndarray, sections: dict, mesh_dir: Path):
    """The :class:`reduction.bundle.Bundle` of ``mesh`` moved to ``x_worn``
    (node coordinates [m]) with the new ``bundle``'s pairs and loads.

    ``W`` (p,) [m]: the total wear depth per new pair, added to each pair's
    gap so a wear study on the worn bundle starts at W = 0. ``sections``:
    ``material``, ``rotation``, ``damping``, ``excitation`` as
    :func:`reduction.assemble.build_bundle` takes them. The worn mesh is
    written to ``mesh_dir/mesh.xdmf`` (+ .h5) for the bundle's extra files;
    ``mesh`` is back at its new coordinates on return.
    """
    from reduction import dolfinx_compat as dc
    from reduction.assemble import DEGREE, build_bundle
    from reduction.pairs import contact_pairs, layout_of

    meta = bundle.meta or {}
    geometry_info = meta.get("geometry") or {}
    unworn = contact_pairs(dc.vector_space(mesh, DEGREE), ft, nodes=layout_of(geometry_info))
    with dc.moved(mesh, x_worn):
        worn, _ = build_bundle(mesh, ct, ft, geometry_info, sections["material"], sections["rotation"],
                               sections["damping"], sections["excitation"], pairs=unworn)
        Path(mesh_dir).mkdir(parents=True, exist_ok=True)
        dc.write_mesh_xdmf(mesh, ct, ft, Path(mesh_dir) / "mesh.xdmf")
    # Same pairs (worn positions moved along n only): match them, then carry the wear into the gap.
    c = worn.contact
    match = match_pairs(bundle.contact.position, c.position, W)
    c.gap = bundle.contact.gap + W[match]
    check_cyclic_faces(bundle, worn)
    worn.meta = dict(worn.meta, worn_from=str(bundle.path), gap_includes_wear=True,
                     max_wear_m=float(W.max(initial=0.0)))
    return worn


def match_pairs(pos_new: np.ndarray, pos_worn: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Index into the new pairs of each worn pair (nearest position [m]; they moved by ≤ W)."""
    from scipy.spatial import cKDTree

    d, i = cKDTree(pos_new).query(pos_worn)
    if len(set(i.tolist())) != len(i) or (len(d) and d.max() > 2.0 * W.max(initial=0.0) + 1e-9):
        raise GeometryError("remap: the worn bundle's contact pairs do not match the new bundle's")
    return i


def check_cyclic_faces(new, worn) -> None:
    """:class:`GeometryError` unless the worn bundle has the new bundle's cyclic
    faces: the same N, and the same matched (low, high) node pairs at the same
    positions (to 1e-12 of the model size [m]; compared by position since the
    worn mesh, read back from XDMF, may number its DOFs differently). Nothing
    to check for a fixed-boundary sector."""
    from scipy.spatial import cKDTree

    a, b = new.cyclic, worn.cyclic
    if a is None:
        return
    if b is None or int(b.n_sectors) != int(a.n_sectors) or a.low_dofs.shape != b.low_dofs.shape:
        raise GeometryError("remap: the worn sector has not the new sector's cyclic faces (cyclic.npz): "
                            "the wear must move flank nodes only, never a cut face")
    if new.coords is None or worn.coords is None:
        raise GeometryError("remap: a cyclic bundle without node coordinates: its cut faces cannot be compared")
    tol = 1e-12 * float(np.abs(new.coords).max(initial=1.0))
    at = lambda bundle, dofs: bundle.coords[np.asarray(dofs)[:, 0] // 3]  # noqa: E731  (one node per DOF row)
    d, i = cKDTree(at(worn, b.low_dofs)).query(at(new, a.low_dofs))
    moved = max(float(d.max(initial=0.0)),
                float(np.abs(at(worn, b.high_dofs)[i] - at(new, a.high_dofs)).max(initial=0.0)))
    if len(set(i.tolist())) != len(i) or moved > tol:
        raise GeometryError(f"remap: the wear moved or re-paired cyclic face nodes (by up to {moved:.3g} m; a flank "
                            "touching a cut face?): the worn sector would no longer be a sector of a tuned disk")


def new_and_worn(bundle, worn, n_freq: int, n_modes: int, new_model=None, cyclic: tuple | None = None) -> dict:
    """The new and the worn reduced models, reduced alike, and their first
    ``n_freq`` tied frequencies [Hz] (full, unreduced models).

    ``new_model``: the reduction stage's model of ``bundle`` (used as is; None:
    ``bundle`` is reduced here). Fixed-boundary sector: Craig–Bampton with
    ``n_modes`` (:func:`reduction.reduce.reduce_bundle`), frequencies of the
    tied sector (:func:`reduction.modes.frequencies`). Cyclic sector: both per
    ND with the new model's EO, harmonics and modes (or ``cyclic`` = (EO, Nh)
    and ``n_modes`` without a new model), frequencies of ND ``EO mod N``
    (:func:`reduction.cyclic_reduce.tied_frequencies`).
    Returns ``{"new", "worn", "freq_new_hz", "freq_worn_hz", "nodal_diameter"}``
    (``nodal_diameter`` None for a fixed-boundary sector).
    """
    from workflow.engine.condense import nodal_diameter_of_harmonic
    from reduction.cyclic_reduce import reduce_cyclic, tied_frequencies
    from reduction.modes import frequencies
    from reduction.reduce import reduce_bundle
    from workflow.errors import BundleError

    if new_model is not None and (bundle.cyclic is not None) != bool(getattr(new_model, "is_cyclic", False)):
        raise BundleError("remap: the reduced model and the bundle disagree on cyclic symmetry "
                          "(cyclic_reduced.npz goes with a bundle that has cyclic.npz)")
    if bundle.cyclic is None:
        reduce = lambda b: reduce_bundle(b, n_modes=n_modes)  # noqa: E731
        new_model = new_model if new_model is not None else reduce(bundle)
        return {"new": new_model, "worn": reduce(worn), "nodal_diameter": None,
                "freq_new_hz": frequencies(bundle, n_freq, tied=True),
                "freq_worn_hz": frequencies(worn, n_freq, tied=True)}
    if new_model is not None:
        eo, nh, n_modes = new_model.engine_order, int(new_model.info["nh_max"]), int(new_model.info["modes"])
    else:
        eo, nh = int(cyclic[0]), int(cyclic[1])
        new_model = reduce_cyclic(bundle, eo, nh, n_modes=n_modes)
    nd = nodal_diameter_of_harmonic(1, eo, int(bundle.cyclic.n_sectors))
    return {"new": new_model, "worn": reduce_cyclic(worn, eo, nh, n_modes=n_modes), "nodal_diameter": nd,
            "freq_new_hz": tied_frequencies(bundle, nd, n_freq), "freq_worn_hz": tied_frequencies(worn, nd, n_freq)}
