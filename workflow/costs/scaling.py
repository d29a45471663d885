"""Scaling of assembly and reduction with the mesh, on 1 and on N MPI processes: the
study of the ``scaling`` stage and of ``python -m workflow.bench.scaling``.

For each mesh-size factor ``s`` (the three sizes h_blade, h_disk, h_airfoil
of the default sector scaled by ``s``; DOFs grow like s⁻³) the study

1. meshes the sector once (gmsh, one process);
2. assembles the bundle (:func:`reduction.assemble.assemble_bundle`: mesh
   read and distributed, M, K(Ω) with prestress, C, bundle written) on 1
   process and under ``mpirun -n P`` for each P;
3. reduces the 1-process bundle (Craig–Bampton, ``--modes`` fixed-interface
   modes) on 1 process (:func:`reduction.reduce.reduce_bundle`) and on P
   ranks (:func:`reduction.parallel.reduce_bundle_mpi`).

Each step is a fresh process (or MPI job), so its peak memory is its own:
``ru_maxrss`` of RUSAGE_SELF + RUSAGE_CHILDREN on every rank, summed over
the ranks (it includes each rank's Python + dolfinx/PETSc baseline, about
0.15–0.2 GB). Wall times are rank 0's, between barriers, excluding process
start-up and imports. Every process runs one BLAS/OpenMP thread, so P
processes use P cores. The tied frequencies of the P-rank reduced model are
checked against the serial one (column ``f_rel_err``).

Output: ``scaling.csv`` (one row per mesh × P), ``scaling.png`` (time and
memory against DOFs, log–log) and ``scaling.json`` (power-law fits
``cost = a·n^b`` over the meshes, per step and P, and their projection to
10⁶ DOFs).
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

MODES = 30
PROJECT_DOFS = 1_000_000


# ----------------------------------------------------------------- workers

def _rss_gb(comm=None) -> float:
    """Peak resident memory [GB] of this process and its children, summed over ``comm``'s ranks."""
    kb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
          + resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    if comm is not None:
        kb = comm.reduce(kb, root=0)
    return kb / 1024 ** 2 if kb is not None else None


def worker_mesh(factor: float, folder: Path) -> dict:
    from geometry.params import SectorParams
    from geometry.sector import build_sector
    from workflow.io import write_json

    base = SectorParams()
    p = replace(base, h_blade=base.h_blade * factor, h_disk=base.h_disk * factor,
                h_airfoil=base.h_airfoil * factor)
    t0 = time.perf_counter()
    info = build_sector(p, folder / "sector.msh")
    write_json(folder / "geometry.json", info)
    return {"mesh_s": time.perf_counter() - t0, "mesh_gb": _rss_gb(), "n_nodes": info.get("n_nodes")}


def worker_assembly(folder: Path, out: Path) -> dict | None:
    from mpi4py import MPI

    from reduction.assemble import assemble_bundle
    from workflow.params import Damping, Excitation, Material, Rotation

    comm = MPI.COMM_WORLD
    info = json.loads((folder / "geometry.json").read_text())
    comm.barrier()
    t0 = time.perf_counter()
    s = assemble_bundle(folder / "sector.msh", info, Material(), Rotation(speed_rpm=10000.0), Damping(),
                        Excitation(), out, comm=comm)
    comm.barrier()
    seconds = time.perf_counter() - t0
    gb = _rss_gb(comm)
    if comm.rank:
        return None
    return {"assembly_s": seconds, "assembly_gb": gb, "n_dofs": s["n_dofs"], "n_pairs": s["n_pairs"],
            "assembly_detail": s["timings"]}


def worker_reduction(bundle: Path, modes: int) -> dict | None:
    import numpy as np
    import scipy.linalg as sla
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    comm.barrier()
    t0 = time.perf_counter()
    if comm.size == 1:
        from reduction.bundle import read_bundle
        from reduction.reduce import reduce_bundle

        model = reduce_bundle(read_bundle(bundle), n_modes=modes)
    else:
        from reduction.parallel import reduce_bundle_mpi

        model = reduce_bundle_mpi(bundle, n_modes=modes, comm=comm)
    comm.barrier()
    seconds = time.perf_counter() - t0
    gb = _rss_gb(comm)
    if comm.rank:
        return None
    N = sla.null_space(model.B)
    w2 = sla.eigh(N.T @ model.K @ N, N.T @ model.M @ N, eigvals_only=True)[:10]
    return {"reduction_s": seconds, "reduction_gb": gb, "reduced_size": model.size,
            "reduction_detail": model.info["seconds"],
            "tied_hz": (np.sqrt(np.abs(w2)) / (2 * np.pi)).tolist()}


def _worker(argv) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("step", choices=("mesh", "assembly", "reduction"))
    ap.add_argument("--dir", type=Path, required=True)
    ap.add_argument("--factor", type=float, default=1.0)
    ap.add_argument("--bundle", type=Path)
    ap.add_argument("--json", type=Path, required=True)
    ap.add_argument("--modes", type=int, default=MODES)
    a = ap.parse_args(argv)
    if a.step == "mesh":
        r = worker_mesh(a.factor, a.dir)
    elif a.step == "assembly":
        r = worker_assembly(a.dir, a.bundle)
    else:
        r = worker_reduction(a.bundle, a.modes)
    if r is not None:
        a.json.write_text(json.dumps(r))
    from workflow.mpi import finish

    finish()  # on every rank together, before MPI_Finalize (else a hang at exit)
    return 0


# ------------------------------------------------------------------ driver

def _launch(step: str, procs: int, json_path: Path, **kw) -> dict:
    from workflow.mpi import mpirun_command, single_thread_env

    cmd = [sys.executable, "-m", "workflow.costs.scaling", step, "--json", str(json_path)]
    for k, v in kw.items():
        cmd += [f"--{k}", str(v)]
    if procs > 1:
        launcher = mpirun_command(procs)
        if launcher is None:
            raise RuntimeError("mpirun not found: cannot run the multi-process cases")
        cmd = launcher + cmd
    env = launch_env(single_thread_env())
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT", "1")
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return json.loads(json_path.read_text())


#: Open MPI settings a user may rely on; every other OMPI_/PMIX_/PMI_ variable
#: belongs to the launch of *this* process and breaks a fresh mpirun started from it
_KEEP = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_MCA_btl", "OMPI_MCA_pml", "OMPI_MCA_mtl", "OMPI_MCA_rmaps_base")


def launch_env(env: dict) -> dict:
    """``env`` without the variables an MPI launch (or an MPI singleton) left in this
    process: a worker started from a rank of ``mpirun`` — or from a process in which
    dolfinx initialised MPI — would otherwise try to join that job."""
    return {k: v for k, v in env.items()
            if not (k.startswith(("OMPI_", "PMIX_", "PMI_")) and not k.startswith(_KEEP))}


def predicted_gb(rows, n_dofs: int) -> float | None:
    """Peak memory [GB] at ``n_dofs`` extrapolated from the largest of assembly and
    reduction over the rows so far (power law through the last two meshes; None if < 2)."""
    import numpy as np

    sizes = sorted({r["n_dofs"] for r in rows})
    if len(sizes) < 2:
        return None
    n = np.array(sizes[-2:], dtype=float)
    y = np.array([max(max(r["assembly_gb"], r["reduction_gb"]) for r in rows if r["n_dofs"] == k)
                  for k in sizes[-2:]])
    b = np.log(y[1] / y[0]) / np.log(n[1] / n[0])
    return float(y[1] * (n_dofs / n[1]) ** b)


def study(factors, procs=(1, 2), modes: int = MODES, work: Path | None = None, log=print,
          max_gb: float | None = None, on_row=None, prior=()) -> list[dict]:
    """Rows of the scaling table (one per mesh factor × process count).

    ``max_gb``: before a finer mesh, its peak memory is extrapolated from the
    two previous meshes (:func:`predicted_gb`, DOFs ∝ factor⁻³ from the last
    one); the study stops there if that exceeds ``max_gb``. ``on_row(rows)``
    is called after every row (the caller writes the table as it grows, so a
    long study that is killed keeps what it measured). ``prior``: rows of an
    earlier study (``--append``), used for the memory extrapolation. A mesh
    that gmsh cannot make at a factor is reported and skipped.
    """
    import tempfile

    import numpy as np

    rows = []
    with tempfile.TemporaryDirectory(dir=work) as tmp:
        for s in factors:
            known = sorted(list(prior) + rows, key=lambda r: r["n_dofs"])
            if max_gb and known:
                last = known[-1]
                n_next = int(last["n_dofs"] * (last["factor"] / s) ** 3)
                gb = predicted_gb(known, n_next)
                if gb is not None and gb > max_gb:
                    log(f"factor {s:g}: ~{n_next} DOFs would need ~{gb:.1f} GB > {max_gb:g} GB: stop")
                    break
            d = Path(tmp) / f"f{s:g}"
            d.mkdir()
            try:
                mesh = _launch("mesh", 1, d / "mesh.json", dir=d, factor=s)
            except RuntimeError as exc:     # e.g. gmsh's quality check at this size: try the next one
                log(f"factor {s:g}: meshing failed, skipped ({str(exc).strip().splitlines()[-1]})")
                continue
            ref = None
            for P in procs:
                asm = _launch("assembly", P, d / f"asm{P}.json", dir=d, bundle=d / f"bundle{P}")
                red = _launch("reduction", P, d / f"red{P}.json", dir=d, bundle=d / f"bundle{procs[0]}",
                              modes=modes)
                if ref is None:
                    ref = red["tied_hz"]
                err = float(np.max(np.abs(np.array(red["tied_hz"]) - ref) / np.array(ref)))
                row = dict(factor=s, procs=P, n_dofs=asm["n_dofs"], n_pairs=asm["n_pairs"],
                           mesh_s=mesh["mesh_s"], assembly_s=asm["assembly_s"], assembly_gb=asm["assembly_gb"],
                           reduction_s=red["reduction_s"], reduction_gb=red["reduction_gb"],
                           reduced_size=red["reduced_size"], f_rel_err=err,
                           **{f"asm_{k}": v for k, v in asm["assembly_detail"].items()},
                           **{f"red_{k}": v for k, v in red["reduction_detail"].items()})
                rows.append(row)
                if on_row is not None:
                    on_row(rows)
                log(f"factor {s:g}, {P} proc: {row['n_dofs']} DOFs; assembly {row['assembly_s']:.2f} s "
                    f"{row['assembly_gb']:.2f} GB; reduction {row['reduction_s']:.2f} s {row['reduction_gb']:.2f} GB; "
                    f"tied f rel. err {err:.1e}")
            for P in procs:
                import shutil

                shutil.rmtree(d / f"bundle{P}", ignore_errors=True)
    return rows


def fits(rows, min_dofs: int = 0) -> dict:
    """Power laws ``y = a n^b`` per (quantity, procs) over rows with ≥ ``min_dofs`` DOFs; projected at 10⁶."""
    import numpy as np

    out = {}
    for q in ("assembly_s", "reduction_s", "assembly_gb", "reduction_gb"):
        for P in sorted({r["procs"] for r in rows}):
            pts = [(r["n_dofs"], r[q]) for r in rows if r["procs"] == P and r["n_dofs"] >= min_dofs]
            if len(pts) < 2:
                continue
            n, y = np.array(pts, dtype=float).T
            b, loga = np.polyfit(np.log(n), np.log(y), 1)
            out[f"{q}@{P}"] = dict(quantity=q, procs=P, a=float(np.exp(loga)), b=float(b),
                                   at_1e6=float(np.exp(loga) * PROJECT_DOFS ** b), points=len(pts))
    return out


def write(rows, fit: dict, out: Path) -> list[Path]:
    from workflow.io import write_json, write_text

    out.mkdir(parents=True, exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    lines = [",".join(keys)] + [",".join(_fmt(r.get(k, "")) for k in keys) for r in rows]
    paths = [write_text(out / "scaling.csv", "\n".join(lines) + "\n"), write_json(out / "scaling.json", fit)]
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np

        from workflow.report.png import finish_axes, write_figure

        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        for ax, unit, qs in ((axes[0], "wall time [s]", ("assembly_s", "reduction_s")),
                             (axes[1], "peak memory, all ranks [GB]", ("assembly_gb", "reduction_gb"))):
            for q, color in zip(qs, ("tab:blue", "tab:red")):
                for P, style in zip(sorted({r["procs"] for r in rows}), ("o-", "s--", "^:", "d-.")):
                    pts = sorted((r["n_dofs"], r[q]) for r in rows if r["procs"] == P)
                    n, y = np.array(pts).T
                    f = fit.get(f"{q}@{P}")
                    lab = f"{q.split('_')[0]}, {P} proc" + (f" (∝ n^{f['b']:.2f})" if f else "")
                    ax.loglog(n, y, style, color=color, label=lab, alpha=1.0 if P == 1 else 0.7)
            finish_axes(ax, "DOFs", unit, which="both")
        fig.suptitle("bladewear: assembly and Craig–Bampton reduction vs DOFs (1 thread per process)")
        write_figure(fig, out / "scaling.png")
        paths.append(out / "scaling.png")
    except ImportError:  # pragma: no cover - matplotlib is a dependency
        pass
    return paths


def summarise(rows, fit_min_dofs: int, seconds: float, **meta) -> dict:
    """:func:`fits` plus ``_study``: this run's seconds, the seconds measured over
    all rows, the largest model, the peak memory, the factors, and ``meta``."""
    fit = fits(rows, fit_min_dofs)
    fit["_study"] = dict(seconds=seconds,
                         measured_seconds=sum(r["assembly_s"] + r["reduction_s"] for r in rows)
                         + sum({r["factor"]: r["mesh_s"] for r in rows}.values()),
                         largest_dofs=max(r["n_dofs"] for r in rows),
                         peak_gb=max(max(r["assembly_gb"], r["reduction_gb"]) for r in rows),
                         factors=",".join(f"{f:g}" for f in sorted({r["factor"] for r in rows}, reverse=True)),
                         fit_min_dofs=fit_min_dofs, **meta)
    return fit


def read_rows(path: Path) -> list[dict]:
    """Rows of an earlier ``scaling.csv`` (numbers parsed), [] if there is none."""
    import csv

    if not Path(path).is_file():
        return []

    def num(v):
        for t in (int, float):
            try:
                return t(v)
            except ValueError:
                pass
        return v

    with open(path, newline="") as fh:
        return [{k: num(v) for k, v in r.items() if v != ""} for r in csv.DictReader(fh)]


def _fmt(v) -> str:
    return f"{v:.6g}" if isinstance(v, float) else str(v)


if __name__ == "__main__":      # a worker process of the study (:func:`_launch`)
    raise SystemExit(_worker(sys.argv[1:]))
