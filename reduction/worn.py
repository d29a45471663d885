"""The worn model: the bundle re-assembled on the remapped mesh (contracts §8).

Wear opens the gap; it does not change who touches whom. On the worn mesh
the flank vertices of a pair are W apart and would no longer match, so the
pairs (DOFs, frames, areas) are taken from the unworn mesh, and the worn
bundle's ``gap`` is the new one plus W: the geometry carries the stiffness
of the removed material, the gap its kinematic opening, neither twice
(``workflow/stages/remap.py`` explains it in full).
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
    from geometry.remap import moved
    from reduction import dolfinx_compat as dc
    from reduction.assemble import DEGREE, build_bundle
    from reduction.pairs import contact_pairs, layout_of

    meta = bundle.meta or {}
    geometry_info = meta.get("geometry") or {}
    unworn = contact_pairs(dc.vector_space(mesh, DEGREE), ft, nodes=layout_of(geometry_info))
    with moved(mesh, x_worn):
        worn, _ = build_bundle(mesh, ct, ft, geometry_info, sections["material"], sections["rotation"],
                               sections["damping"], sections["excitation"], pairs=unworn)
        Path(mesh_dir).mkdir(parents=True, exist_ok=True)
        dc.write_mesh_xdmf(mesh, ct, ft, Path(mesh_dir) / "mesh.xdmf")
    # Same pairs (worn positions moved along n only): match them, then carry the wear into the gap.
    c = worn.contact
    match = match_pairs(bundle.contact.position, c.position, W)
    c.gap = bundle.contact.gap + W[match]
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
