"""Mesh convergence of the sector's first tied frequencies.

``python -m workflow.bench.mesh_convergence [--factors 1,0.8,0.6] [--rpm 0]
[--out results/mesh_convergence.csv]``: scales the three mesh sizes
(h_blade, h_disk, h_airfoil) of the default sector by each factor, assembles
(P2) and writes one CSV row per mesh: factor, sizes, DOFs, the first tied
frequencies [Hz], and the seconds spent meshing, assembling and solving. The
last column ``rel_change_f1`` is the change of f₁ from the previous
(coarser) row.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

N_MODES = 5


def study(factors, rpm: float = 0.0, n_modes: int = N_MODES, base=None):
    """Rows (dicts) of the convergence table, coarse to fine."""
    from geometry.params import SectorParams
    from geometry.sector import build_sector
    from reduction import dolfinx_compat as dc
    from reduction.assemble import build_bundle
    from reduction.modes import frequencies
    from workflow.params import Damping, Material, Rotation

    base = base or SectorParams()
    rows, prev = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for s in factors:
            p = replace(base, h_blade=base.h_blade * s, h_disk=base.h_disk * s, h_airfoil=base.h_airfoil * s)
            t0 = time.perf_counter()
            info = build_sector(p, Path(tmp) / "sector.msh")
            t1 = time.perf_counter()
            mesh, ct, ft = dc.read_msh(Path(tmp) / "sector.msh")
            bundle, summ = build_bundle(mesh, ct, ft, info, Material(), Rotation(speed_rpm=rpm), Damping(modal_ratio=0.0),
                                        None)
            t2 = time.perf_counter()
            f = frequencies(bundle, n_modes, tied=True)
            t3 = time.perf_counter()
            row = dict(factor=s, h_blade=p.h_blade, h_disk=p.h_disk, h_airfoil=p.h_airfoil, n_dofs=bundle.n_dofs,
                       n_elements=info.get("n_elements"), **{f"f{i + 1}_hz": float(v) for i, v in enumerate(f)},
                       mesh_s=t1 - t0, assembly_s=t2 - t1, eigen_s=t3 - t2,
                       rel_change_f1=(f[0] - prev) / prev if prev else float("nan"))
            prev = f[0]
            rows.append(row)
            print(", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()), flush=True)
    return rows


def write_csv(rows, path) -> Path:
    from workflow.io import write_rows

    return write_rows(path, rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--factors", default="1,0.8,0.65,0.5,0.4")
    ap.add_argument("--rpm", type=float, default=0.0)
    ap.add_argument("--out", default="results/mesh_convergence.csv")
    a = ap.parse_args(argv)
    rows = study([float(v) for v in a.factors.split(",")], a.rpm)
    print(write_csv(rows, a.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
