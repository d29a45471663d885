"""Geometry stage: the blade–disk sector mesh (contracts §1, §8).

Writes ``sector.msh`` (gmsh 4.1, tagged physical groups) and
``geometry.json`` (the info dict of :func:`geometry.sector.build_sector`:
volumes, tip point, excitation direction, flank pairing…) under ``out``.
"""
from __future__ import annotations

from pathlib import Path

from workflow.io import write_json

NAME = "geometry"
SECTIONS = ("geometry",)
NEEDS = ()
PRODUCES = ("mesh",)
MPI = False  # gmsh meshes on rank 0 alone; the assembly then distributes the mesh over the ranks

MESH_FILE = "sector.msh"
INFO_FILE = "geometry.json"


#: Above this many estimated elements the stage warns before meshing (minutes, GBs).
WARN_ELEMENTS = 200_000
#: Measured peak memory of meshing + assembly per element (span = 100: ~630k elements, 2.6 GB).
BYTES_PER_ELEMENT = 4.2e3


def run(scene, inputs: dict, out: Path, log) -> dict:
    """Build the sector of ``scene["geometry"]``; return counts and file names."""
    from geometry.params import estimate_elements
    from geometry.sector import build_sector

    out = Path(out)
    est = estimate_elements(scene["geometry"])
    total = sum(est.values())
    log.info(f"meshing ~{total:,.0f} tetrahedra (estimated: " + ", ".join(f"{k} ~{v:,.0f}" for k, v in est.items())
             + ")")
    if total > WARN_ELEMENTS:
        big = max(est, key=est.get)
        log.warning(f"a large mesh: ~{total:,.0f} elements need minutes and ~{total * BYTES_PER_ELEMENT / 1e9:.1f} GB "
                    f"to mesh and assemble; geometry.{big} = {getattr(scene['geometry'], big)} m sets most of it")
    info = build_sector(scene["geometry"], out / MESH_FILE)
    write_json(out / INFO_FILE, info)
    log.info(f"sector: {info.get('n_nodes')} nodes, {info.get('n_elements')} elements, "
             f"{info.get('contact_pairs')} contact pairs")
    keys = ("n_nodes", "n_elements", "n_vertices", "contact_pairs", "pair_distance_max", "volume_blade_m3",
            "volume_disk_m3", "quality_min", "jacobian_ratio_min")
    summary = {k: info[k] for k in keys if k in info}
    summary.update(mesh=MESH_FILE, info=INFO_FILE, estimated_elements=round(total))
    return summary
