"""Cyclic-modes stage: the tuned disk's nodal-diameter map, Campbell diagram and ZZENF (docs/cyclic.md).

Reads a bundle with cyclic faces (``geometry.cyclic = true``; ``cyclic.npz``)
and solves each nodal diameter's Hermitian sector problem with the interface
tied (:mod:`reduction.cyclic_modes`). Writes

* ``nd_map.csv`` (nd, mode, f_hz) at the bundle's speed and ``nd_map.png``;
* with ``cyclic.campbell_speeds_rpm``: ``campbell.csv`` (speed_rpm, nd,
  mode, f_hz; K(Ω) re-assembled from the geometry stage's mesh at each
  speed), ``campbell_crossings.csv`` (eo, nd, mode, speed_rpm, f_hz) and
  ``campbell.png`` with the engine-order lines;
* ``zzenf.csv`` (modes near an EO's excitation at the bundle's speed) and
  ``zzenf.png``.
"""
from __future__ import annotations

from pathlib import Path

NAME = "cyclic_modes"
SECTIONS = ("cyclic", "material", "rotation")
NEEDS = ("mesh", "bundle")
PRODUCES = ("cyclic_modes",)


def _nodal_diameters(cfg, n_sectors: int) -> list[int]:
    """The scene's NDs folded into 0 … N/2 (k and N − k share their frequencies), or all of them."""
    from reduction.cyclic_modes import fold_nd, nodal_diameters
    from workflow.errors import SceneError

    if not cfg.nodal_diameters:
        return nodal_diameters(n_sectors)
    bad = [k for k in cfg.nodal_diameters if k >= n_sectors]
    if bad:
        raise SceneError(f"cyclic.nodal_diameters contains {bad[0]}: the disk has N = {n_sectors} sectors, "
                         f"NDs are 0 … {n_sectors // 2} (k > N/2 is the same as N − k)")
    return sorted({fold_nd(k, n_sectors) for k in cfg.nodal_diameters})


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction import cyclic_modes as cm
    from reduction.bundle import read_bundle
    from reduction.constraints import constraint_map
    from workflow.errors import BundleError
    from workflow.io import write_rows
    from workflow.report import cyclic as fig
    from workflow.stages.assembly import bundle_folder
    from workflow.stages.geometry import MESH_FILE

    cfg, out = scene["cyclic"], Path(out)
    bundle = read_bundle(bundle_folder(inputs["bundle"]))
    if bundle.cyclic is None:
        raise BundleError(f"{bundle.path}: no cyclic.npz — the cyclic_modes product needs a sector with cyclic "
                          "faces: set geometry.cyclic = true")
    N = bundle.cyclic.n_sectors
    nds = _nodal_diameters(cfg, N)
    speed = float(bundle.meta.get("speed_rpm", scene["rotation"].speed_rpm))
    base = constraint_map(bundle, tied=True)
    F, t_map = cm.nd_map(bundle.K, bundle.M, base, bundle.cyclic, nds, cfg.modes_per_nd)
    rows = [dict(nd=k, mode=j + 1, f_hz=float(F[i, j])) for i, k in enumerate(nds) for j in range(F.shape[1])]
    write_rows(out / "nd_map.csv", rows)
    fig.nd_map_figure(nds, F, speed, N, out / "nd_map.png")
    log.info(f"ND map: {len(nds)} NDs × {cfg.modes_per_nd} modes in {t_map:.2f} s; first family "
             f"{F[:, 0].min():.1f} … {F[:, 0].max():.1f} Hz")
    eos = sorted({int(cfg.engine_order), *map(int, cfg.engine_order_lines)})
    summary = dict(n_sectors=N, n_dofs=bundle.n_dofs, speed_rpm=speed, nodal_diameters=nds,
                   modes_per_nd=cfg.modes_per_nd, engine_order=cfg.engine_order, rows=rows,
                   first_family_hz=[float(v) for v in F[:, 0]], nd_map_s=t_map, files=["nd_map.csv"])
    if cfg.campbell_speeds_rpm:
        extra = _campbell(scene, cfg, inputs["mesh"], MESH_FILE, bundle, base, nds, eos, out, log)
        summary["files"] += extra.pop("files")
        summary.update(extra)
    res = cm.zzenf_resonances(F, nds, None, N, speed, cfg.zzenf_band)
    if res:
        write_rows(out / "zzenf.csv", res)
        summary["files"].append("zzenf.csv")
    fig.zzenf_figure(nds, F, speed, N, int(cfg.engine_order), res, out / "zzenf.png")
    summary.update(zzenf=res, figures=sorted(p.name for p in out.glob("*.png")))
    return summary


def _campbell(scene, cfg, mesh_folder, mesh_file, bundle, base, nds, eos, out: Path, log) -> dict:
    """Campbell diagram and EO crossings: files and summary entries."""
    import numpy as np

    from reduction import cyclic_modes as cm
    from reduction.assemble import rpm_to_rad_s
    from workflow.io import write_rows
    from workflow.report import cyclic as fig

    N = bundle.cyclic.n_sectors
    rpm = sorted(float(v) for v in cfg.campbell_speeds_rpm)
    K_of = cm.stiffness_function(Path(mesh_folder) / mesh_file, scene["material"], scene["rotation"], bundle)
    Fc, seconds = cm.campbell(K_of, bundle.M, base, bundle.cyclic, nds, cfg.modes_per_nd,
                              [rpm_to_rad_s(v) for v in rpm])
    write_rows(out / "campbell.csv", [dict(speed_rpm=s, nd=k, mode=j + 1, f_hz=float(Fc[a, i, j]))
                                      for a, s in enumerate(rpm) for i, k in enumerate(nds)
                                      for j in range(Fc.shape[2])])
    cross = cm.eo_crossings(rpm, Fc, nds, eos, N)
    files = ["campbell.csv"]
    if cross:
        write_rows(out / "campbell_crossings.csv", cross)
        files.append("campbell_crossings.csv")
    fig.campbell_figure(rpm, nds, Fc, eos, N, cross, out / "campbell.png")
    log.info(f"Campbell: {len(rpm)} speeds × {len(nds)} NDs in {seconds:.1f} s "
             f"({seconds / len(rpm):.2f} s per speed); {len(cross)} EO crossings")
    return dict(campbell_speeds_rpm=rpm, campbell_s=seconds, campbell_crossings=cross,
                campbell_first_family_hz=np.asarray(Fc[:, :, 0]).tolist(), files=files)
