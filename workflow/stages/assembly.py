"""Assembly stage: the sector mesh → the model bundle (contracts §2, §8).

Reads ``sector.msh`` and ``geometry.json`` from the geometry stage's folder
and writes the bundle folder ``out/model`` with
:func:`reduction.assemble.assemble_bundle` (M, K(Ω), C, contact pairs, loads,
node coordinates, mesh.xdmf, meta.json).
"""
from __future__ import annotations

import json
from pathlib import Path

from workflow.errors import GeometryError

NAME = "assembly"
SECTIONS = ("material", "rotation", "damping", "excitation")
NEEDS = ("mesh",)
PRODUCES = ("bundle",)
MPI = True  # collective under mpirun: dolfinx distributes the mesh and assembles in parallel; rank 0 writes

BUNDLE_DIR = "model"


def read_geometry(folder: Path) -> tuple[Path, dict]:
    """(mesh path, geometry info) from the geometry stage's folder."""
    from workflow.stages.geometry import INFO_FILE, MESH_FILE

    msh, info = Path(folder) / MESH_FILE, Path(folder) / INFO_FILE
    for f in (msh, info):
        if not f.is_file():
            raise GeometryError(f"geometry output {f} is missing (run the geometry stage)")
    try:
        return msh, json.loads(info.read_text())
    except ValueError as exc:
        raise GeometryError(f"geometry output {info} is not valid JSON: {exc}") from exc


def bundle_folder(folder: Path) -> Path:
    """The bundle behind a ``bundle`` product folder: ``folder/model`` when the
    assembly stage made it, else ``folder`` itself (a user's ``[model] bundle``)."""
    folder = Path(folder)
    return folder / BUNDLE_DIR if (folder / BUNDLE_DIR / "M.npz").is_file() else folder


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.assemble import assemble_bundle

    msh, info = read_geometry(inputs["mesh"])
    out = Path(out)
    s = assemble_bundle(msh, info, scene["material"], scene["rotation"], scene["damping"], scene["excitation"],
                        out / BUNDLE_DIR)
    log.info(f"bundle: {s['n_dofs']} DOFs, {s['n_pairs']} pairs, mass {s['mass_kg']:.6g} kg, "
             f"first tied mode {s['first_tied_hz'] or float('nan'):.6g} Hz")
    return {
        "n_dofs": s["n_dofs"], "n_pairs": s["n_pairs"], "mass_kg": s["mass_kg"],
        "volume_m3": info.get("volume_blade_m3", 0.0) + info.get("volume_disk_m3", 0.0),
        "volume_fe_m3": s["volume_fe_m3"], "flank_area_m2": s["flank_area_m2"],
        "omega_rad_s": s["omega_rad_s"], "first_tied_hz": s["first_tied_hz"], "damping": s["damping"],
        "prestress": s["prestress"], "timings": s["timings"], "bundle": BUNDLE_DIR,
    }
