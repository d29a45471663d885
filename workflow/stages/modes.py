"""Modes stage: eigenfrequencies of the full model with the interface tied.

Reads the bundle (``<bundle product>/model`` from the assembly stage, or the
folder itself for a user's ``[model] bundle``), solves
``Tᵀ K T φ = ω² Tᵀ M T φ`` (:mod:`reduction.modes`) and writes
``modes.csv`` (mode, f_tied_hz).
"""
from __future__ import annotations

import time
from pathlib import Path

NAME = "modes"
SECTIONS = ("modes",)
NEEDS = ("bundle",)
PRODUCES = ("modes",)
MPI = True  # collective under mpirun: SLEPc shift-invert with parallel MUMPS (reduction.parallel)


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.bundle import read_bundle
    from workflow.io import write_text
    from workflow.mpi import world
    from workflow.stages.assembly import bundle_folder

    comm = world()
    root = comm is None or comm.Get_rank() == 0
    bundle = read_bundle(bundle_folder(inputs["bundle"])) if root else None
    n = int(scene["modes"].count)
    t0 = time.perf_counter()
    if comm is None:
        from reduction.modes import frequencies

        f = frequencies(bundle, n, tied=True)
    else:
        from reduction.parallel import frequencies_mpi

        f = frequencies_mpi(bundle, n, tied=True, comm=comm)
    seconds = time.perf_counter() - t0
    if not root:
        return None
    write_text(Path(out) / "modes.csv", "mode,f_tied_hz\n" + "".join(f"{i + 1},{v:.9g}\n" for i, v in enumerate(f)))
    log.info("tied eigenfrequencies [Hz]: " + ", ".join(f"{v:.1f}" for v in f))
    return {"eigenfrequencies_hz": [float(v) for v in f], "n_dofs": bundle.n_dofs, "seconds": seconds,
            "table": "modes.csv"}
