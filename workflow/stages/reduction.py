"""Reduction stage: the model bundle → the reduced model (contracts §4, §8).

Craig–Bampton onto the contact interface (:func:`reduction.reduce.reduce_bundle`)
with ``[reduction] modes`` fixed-interface modes (or every mode below
``cutoff_hz`` when ``modes = 0``); writes ``out/reduced.npz``. The pipeline's
cache keys this on the bundle's content, so a sweep never re-reduces an
unchanged model.
"""
from __future__ import annotations

import time
from pathlib import Path

NAME = "reduction"
SECTIONS = ("reduction",)
NEEDS = ("bundle",)
PRODUCES = ("reduced",)

MPI = True  # collective under mpirun: reduction.parallel (every rank reads its rows; rank 0 writes)

REDUCED_FILE = "reduced.npz"


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.bundle import read_bundle
    from workflow.mpi import world
    from workflow.stages.assembly import bundle_folder

    cfg = scene["reduction"]
    comm = world()
    if comm is not None:
        return _run_parallel(cfg, bundle_folder(inputs["bundle"]), Path(out), log, comm)
    from reduction.reduce import reduce_bundle

    bundle = read_bundle(bundle_folder(inputs["bundle"]))
    log.info(f"reducing {bundle.n_dofs} DOFs, {bundle.contact.n_pairs} contact pairs")
    t0 = time.perf_counter()
    model = reduce_bundle(bundle, n_modes=cfg.modes or None, cutoff_hz=cfg.cutoff_hz or None)
    seconds = time.perf_counter() - t0
    model.save(Path(out) / REDUCED_FILE)
    return _summary(model, seconds, log)


def _run_parallel(cfg, folder: Path, out: Path, log, comm) -> dict | None:
    from reduction.parallel import reduce_bundle_mpi

    log.info(f"reducing {folder} on {comm.Get_size()} MPI ranks")
    t0 = time.perf_counter()
    model = reduce_bundle_mpi(folder, n_modes=cfg.modes or None, cutoff_hz=cfg.cutoff_hz or None, comm=comm)
    seconds = time.perf_counter() - t0
    if model is None:  # not rank 0: the pipeline writes rank 0's summary
        return None
    model.save(out / REDUCED_FILE)
    return _summary(model, seconds, log)


def _summary(model, seconds: float, log) -> dict:
    info = model.info
    log.info(f"{info['modes']} fixed-interface modes (up to {max(info['fixed_interface_hz'], default=0):.0f} Hz) + "
             f"{info['boundary_dofs']} boundary DOFs + {info['load_vectors']} load vectors = {model.size} "
             f"coordinates in {seconds:.1f} s")
    summary = {"modes": info["modes"], "boundary_dofs": info["boundary_dofs"], "load_vectors": info["load_vectors"],
               "size": model.size, "seconds": seconds, "seconds_detail": info["seconds"], "reduced": REDUCED_FILE}
    if "mpi_ranks" in info:
        summary["mpi_ranks"] = info["mpi_ranks"]
    return summary
