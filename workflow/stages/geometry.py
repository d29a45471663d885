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


def run(scene, inputs: dict, out: Path, log) -> dict:
    """Build the sector of ``scene["geometry"]``; return counts and file names."""
    from geometry.sector import build_sector

    out = Path(out)
    info = build_sector(scene["geometry"], out / MESH_FILE)
    write_json(out / INFO_FILE, info)
    log.info(f"sector: {info.get('n_nodes')} nodes, {info.get('n_elements')} elements, "
             f"{info.get('contact_pairs')} contact pairs")
    keys = ("n_nodes", "n_elements", "n_vertices", "contact_pairs", "pair_distance_max", "volume_blade_m3",
            "volume_disk_m3", "quality_min", "jacobian_ratio_min")
    summary = {k: info[k] for k in keys if k in info}
    summary.update(mesh=MESH_FILE, info=INFO_FILE)
    return summary
