"""Reduction stage: the model bundle → the reduced model (contracts §4, §8).

Craig–Bampton onto the contact interface (:func:`reduction.reduce.reduce_bundle`)
with ``[reduction] modes`` fixed-interface modes (or every mode below
``cutoff_hz`` when ``modes = 0``); writes ``out/reduced.npz``. The pipeline's
cache keys this on the bundle's content, so a sweep never re-reduces an
unchanged model.

A cyclic sector bundle (``cyclic.npz``: ``geometry.cyclic = true``) is
reduced per nodal diameter instead (:func:`reduction.cyclic_reduce.reduce_cyclic`:
the NDs ``(j·EO) mod N`` of harmonics j = 0 … ``reduction.cyclic_harmonics``
under ``cyclic.engine_order``) into ``out/cyclic_reduced.npz``;
:func:`load_model` gives the hb and wear stages whichever was written.
"""
from __future__ import annotations

import time
from pathlib import Path

NAME = "reduction"
SECTIONS = ("reduction", "cyclic")
NEEDS = ("bundle",)
PRODUCES = ("reduced",)

MPI = True  # collective under mpirun: reduction.parallel (every rank reads its rows; rank 0 writes)

REDUCED_FILE = "reduced.npz"
CYCLIC_FILE = "cyclic_reduced.npz"


def run(scene, inputs: dict, out: Path, log) -> dict:
    from reduction.bundle import read_bundle
    from workflow.mpi import world
    from workflow.stages.assembly import bundle_folder

    cfg = scene["reduction"]
    comm = world()
    if read_bundle(bundle_folder(inputs["bundle"]), matrices=False).cyclic is not None:
        if comm is not None and comm.Get_rank() != 0:
            return None  # the per-ND reduction is serial: rank 0 does it
        return _run_cyclic(scene, read_bundle(bundle_folder(inputs["bundle"])), Path(out), log)
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


def _run_cyclic(scene, bundle, out: Path, log) -> dict:
    from reduction.cyclic_reduce import reduce_cyclic
    from workflow.errors import SceneError

    cfg, eo = scene["reduction"], int(scene["cyclic"].engine_order)
    if not cfg.modes:
        raise SceneError("reduction.modes = 0: the cyclic (per nodal diameter) reduction keeps a count of "
                         "fixed-interface modes; set reduction.modes > 0")
    log.info(f"cyclic sector of {bundle.cyclic.n_sectors}: reducing {bundle.n_dofs} DOFs per nodal diameter of "
             f"harmonics 0…{cfg.cyclic_harmonics} under engine order {eo}")
    model = reduce_cyclic(bundle, eo, cfg.cyclic_harmonics, n_modes=cfg.modes)
    model.save(out / CYCLIC_FILE)
    per = model.info["seconds_per_nd"]
    log.info(f"{len(per)} nodal diameters {sorted(per)}: " +
             ", ".join(f"ND {k} {v:.2f} s ({model.models[k].size} coordinates)" for k, v in per.items()))
    return {"cyclic": True, "n_sectors": model.n_sectors, "engine_order": eo, "nodal_diameters": sorted(per),
            "modes": int(cfg.modes), "size": {str(k): m.size for k, m in model.models.items()},
            "seconds_per_nd": {str(k): round(v, 3) for k, v in per.items()},
            "seconds": round(model.info["seconds"], 3), "reduced": CYCLIC_FILE}


def load_model(folder: Path, contact=None):
    """The model the reduction stage wrote in ``folder``: a
    :class:`~reduction.cyclic_reduce.CyclicReducedModel` (cyclic sector) or a
    :class:`~workflow.engine.model.ReducedModel`; :class:`BundleError` if neither. With the scene's
    ``contact`` section, the model the contact sees (:func:`contact_model`)."""
    from reduction.cyclic_reduce import CyclicReducedModel
    from workflow.engine.model import ReducedModel
    from workflow.errors import BundleError

    folder = Path(folder)
    if (folder / CYCLIC_FILE).exists():
        model = CyclicReducedModel.load(folder / CYCLIC_FILE)
    elif not (folder / REDUCED_FILE).exists():
        raise BundleError(f"reduced model {folder / REDUCED_FILE} is missing (the reduction stage writes it)")
    else:
        model = ReducedModel.load(folder / REDUCED_FILE)
    return model if contact is None else contact_model(model, contact)


def contact_model(model, contact):
    """``model`` with the interface layer of the scene's ``contact`` section
    (``contact.stiffness_n``, ``stiffness_t``; :mod:`reduction.layer`), or ``model`` itself for
    the rigid contact: the one place a stage's model gets its contact stiffness."""
    from reduction.layer import with_interface_layer

    return with_interface_layer(model, contact.stiffness_n, contact.stiffness_t)


def contact_stiffness(contact) -> dict | None:
    """What a result's summary says of the contact's interface layer (None: rigid)."""
    if not contact.layered:
        return None
    return {"normal_n_per_m3": float(contact.stiffness_n), "tangential_n_per_m3": float(contact.stiffness_t)}


def rigid_contact_only(contact, stage: str) -> None:
    """:class:`SceneError` where a stage that takes the rigid contact only is given a layer."""
    from workflow.errors import SceneError

    if contact.layered:
        raise SceneError(f"contact.stiffness_n = {contact.stiffness_n:g}, contact.stiffness_t = "
                         f"{contact.stiffness_t:g}: the {stage} stage takes the rigid contact (both 0)")


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
