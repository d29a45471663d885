"""Remap stage: the wear depth back onto the geometry (contracts §8).

Reads the bundle (``mesh.xdmf`` with its tags and the contact pairs) and the
wear stage's ``wear.csv``; writes under ``out``:

* ``wear_map.xdmf`` (+ .h5): the mesh with ``wear_depth`` (m, each body's
  share on its flanks) and ``wear_motion`` (m) — open in ParaView;
* ``worn_mesh.xdmf`` (+ .h5): the worn mesh with its tags;
* ``worn_nodes.npz``: worn/new coordinates by gmsh node tag (for a ``.msh``);
* ``figures/wear_flanks.png``, ``figures/wear_sector.png``;
* with ``remap.reassemble``: ``model/`` the worn bundle (same loads and
  material), ``reduced.npz`` its Craig–Bampton reduction (same
  ``reduction.modes`` as the reduction stage) so a scene can continue a wear
  study on the worn geometry, the first tied frequencies new vs worn
  (``freq_shift_hz``), and a short nonlinear FRF of the new and the worn
  reduced models around the first excited tied mode (``frf_peak_hz``,
  ``frf_peak_amplitude_m``, ``figures/frf_worn_vs_new.png``). A cyclic
  sector (tuned disk) stays cyclic: ``cyclic_reduced.npz`` (per ND, as the
  reduction stage), frequencies of ND ``EO mod N`` (``freq_nodal_diameter``).

Where the wear lives in the worn model (geometry *and* gap, not twice)
----------------------------------------------------------------------
The contact pairs are node-to-node and the contact law never reads the
coordinates: its normal gap is ``g = u_N + gap + W`` (contracts §6), with
``u_N`` measured from the reference configuration of the model it runs on.
The worn geometry moves each blade flank node by ``+W_blade n`` and its disk
partner by ``−W_disk n``, so in the worn reference configuration the pair is
already ``W`` apart; the bundle's ``gap`` must say so, hence
``gap_worn = gap_new + W``, and a wear study on the worn bundle starts at
``W = 0``. The geometry carries the *stiffness* effect of the removed
material (frequencies, static flexibility), the gap carries the *kinematic*
opening; neither counts the wear twice. Check (``tests/geometry/
test_remap_stage.py``): the worn model's static contact state equals the new
model's with the wear applied as ``W`` in its contact law, up to the
(tiny, O(W/h)) stiffness change of the removed material.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from workflow.errors import GeometryError, SolverError

NAME = "remap"
SECTIONS = ("remap", "wear", "contact", "hb", "sweep", "pseudotime")  # the worn-vs-new FRF reads the last four
# "reduced": the new model's reduction (same settings as the worn one) for the
# new-vs-worn FRF; the wear stage needs it anyway, so it costs nothing.
NEEDS = ("bundle", "wear", "reduced")
PRODUCES = ("wear_map",)

WEAR_CSV = "wear.csv"
FIG_DIR = "figures"
#: Tied frequencies compared new vs worn at most (the summary's freq_shift_hz).
N_FREQ = 6
#: Points of the new-vs-worn nonlinear FRF: the scene's sweep.points clipped to this range.
FRF_POINTS = (9, 15)
FRF_FIGURE = "frf_worn_vs_new.png"
#: The self-contained interactive 3D page of the worn sector (workflow/report/viewer3d.py).
VIEWER = "wear_3d.html"


# ------------------------------------------------------------------- the stage

def run(scene, inputs: dict, out: Path, log) -> dict:
    from geometry import remap as rm
    from reduction import dolfinx_compat as dc
    from reduction.bundle import read_bundle
    from workflow import render
    from workflow.report.wear import read_wear_csv
    from workflow.stages.assembly import bundle_folder

    out = Path(out)
    rp, wp = scene["remap"], scene["wear"]
    bdir = bundle_folder(inputs["bundle"])
    bundle = read_bundle(bdir)
    if not (bdir / "mesh.xdmf").is_file():
        raise GeometryError(f"bundle {bdir} has no mesh.xdmf: the wear cannot be mapped onto a mesh "
                            f"(a user bundle needs its mesh for the remap stage)")
    table = read_wear_csv(Path(inputs["wear"]) / WEAR_CSV, getattr(wp, "methods", ()))
    pairs = rm.pair_wear(bundle.contact, table, wp.blade_share)
    # Remap is a serial stage: under mpirun it runs on rank 0 while the other
    # ranks wait outside MPI collectives, so the mesh must be read on
    # COMM_SELF (a COMM_WORLD read would wait for them forever).
    from mpi4py import MPI

    mesh, ct, ft = dc.read_mesh_xdmf(bdir / "mesh.xdmf", comm=MPI.COMM_SELF)
    r = rm.remap_wear(mesh, ft, pairs, rp.max_fraction, rp.smoothing)
    share_max = float(max(pairs.w_blade.max(initial=0.0), pairs.w_disk.max(initial=0.0)))
    log.info(f"remap: wear column {table['method']!r}, max share {share_max:.3g} m, "
             f"max motion {r.max_node_motion:.3g} m = {r.max_fraction:.3g} × local element size, "
             f"smallest det ratio {r.orientation:.3g}")

    rm.write_wear_xdmf(out / "wear_map.xdmf", mesh, r, ct, ft)
    rm.write_worn_xdmf(out / "worn_mesh.xdmf", mesh, r, ct, ft)
    rm.write_worn_nodes(out / "worn_nodes.npz", mesh, r)

    surfaces = rm.flank_surfaces(mesh, ft, r, pairs)
    cells, types, points = dc.vtk_mesh(mesh)
    body = np.zeros(len(types), dtype=int)
    body[ct.indices] = ct.values
    figs = render.together([
        (render.render_flank_wear, (surfaces, out / FIG_DIR / "wear_flanks.png", rp.image_width),
         dict(title=f"wear depth ({table['method']}) on each flank")),
        (render.render_sector, (cells, types, points, body, surfaces, out / FIG_DIR / "wear_sector.png",
                                rp.image_width), {})])

    viewer = write_viewer_3d(out / VIEWER, points, cells, types, body, surfaces, table["method"])
    summary = {
        "viewer_3d": viewer, "viewer_3d_bytes": (out / viewer).stat().st_size,
        "wear_map": "wear_map.xdmf", "worn_mesh": "worn_mesh.xdmf", "worn_nodes": "worn_nodes.npz",
        "figures": [str(Path(f).relative_to(out)) for f in figs], "wear_column": table["method"],
        "max_node_motion_m": r.max_node_motion, "max_wear_share_m": share_max,
        "max_motion_fraction": r.max_fraction, "max_fraction_allowed": rp.max_fraction,
        "min_det_ratio": r.orientation, "smoothing": rp.smoothing, "freq_shift_hz": [],
    }
    if rp.reassemble:
        summary.update(reassemble(scene, bundle, mesh, ct, ft, r, pairs, out, log, inputs.get("reduced")))
        if summary.get("frf_figure"):
            summary["figures"].append(summary["frf_figure"])
        summary["unconverged"] = _unconverged(summary)
    # ``out`` is a temporary (cache) folder: name the files as they appear in the
    # run folder, <run>/remap/..., next to the summary.json the CLI prints.
    for f in summary["figures"]:
        log.note(f"remap: figure {NAME}/{f}")
    log.info(f"remap: wear map {NAME}/{summary['wear_map']} (ParaView), worn mesh {NAME}/{summary['worn_mesh']}"
             + (f", worn reduced model {NAME}/{summary['reduced']}" if summary.get("reduced") else ""))
    return summary


def _unconverged(summary: dict) -> list[str]:
    """Lines for the pipeline's ``unconverged`` list (exit status 3): the new-vs-worn FRF."""
    if summary.get("frf_error"):
        return [f"new-vs-worn FRF not computed: {summary['frf_error']}"]
    n = summary.get("frf_points", 0)
    return [f"new-vs-worn FRF, {key} model: {n - got}/{n} frequencies did not converge"
            for key, got in (summary.get("frf_converged") or {}).items() if got < n]


def write_viewer_3d(path: Path, points, cells, types, body, surfaces, method: str) -> str:
    """The interactive 3D page (sector + flanks coloured by wear depth) at ``path``; returns its name."""
    from workflow.report.viewer3d import write_viewer

    deepest = max(surfaces, key=lambda s: float(np.max(s.wear)) if len(s.wear) else 0.0, default=None)
    note = ""
    if deepest is not None and len(deepest.wear):
        i = int(np.argmax(deepest.wear))
        x = np.asarray(deepest.points[i]) * 1e3
        note = (f"deepest wear {deepest.wear[i] * 1e6:.3g} µm ({method}; each body wears its share of W) "
                f"on the {deepest.label}, "
                f"at x, y, z = {x[0]:.1f}, {x[1]:.1f}, {x[2]:.1f} mm")
    write_viewer(path, points, cells, types, body, surfaces, "worn sector: flanks coloured by wear depth", note)
    return Path(path).name


def reassemble(scene, bundle, mesh, ct, ft, r, pairs, out: Path, log, reduced_dir=None) -> dict:
    """Assemble the worn model (new bundle under ``out/model``,
    :func:`reduction.worn.worn_bundle`), reduce it, compare the first tied
    frequencies and the nonlinear FRF peak of the new and the worn reduced
    models (:func:`reduction.worn.new_and_worn`).

    The new reduced model is the reduction stage's in ``reduced_dir`` when
    given, else the new bundle reduced here with the same settings. A cyclic
    sector is reduced per ND (``cyclic_reduced.npz``) and its frequencies are
    those of ND ``EO mod N`` (``freq_nodal_diameter``); else ``reduced.npz``.
    """
    import time

    from reduction.assemble import as_section
    from reduction.bundle import write_bundle
    from reduction.worn import new_and_worn, worn_bundle
    from workflow.stages.reduction import CYCLIC_FILE, REDUCED_FILE, load_model

    t0 = time.perf_counter()
    sections = {k: scene.get(k) for k in ("rotation", "damping", "excitation")}
    sections["material"] = scene.get("material") or as_section((bundle.meta or {}).get("material"))
    stage = out / ".worn-mesh"
    worn = worn_bundle(bundle, mesh, ct, ft, r.x, pairs.w_blade + pairs.w_disk, sections, stage)
    write_bundle(worn, out / "model", extra_files={"mesh.xdmf": stage / "mesh.xdmf", "mesh.h5": stage / "mesh.h5"})
    stage.rmdir()
    n = min(N_FREQ, int(getattr(scene.get("modes"), "count", N_FREQ)))
    red, cyc = scene.get("reduction"), scene.get("cyclic")
    have = reduced_dir is not None and any((Path(reduced_dir) / f).is_file() for f in (CYCLIC_FILE, REDUCED_FILE))
    m = new_and_worn(bundle, worn, n, int(getattr(red, "modes", 30)), load_model(reduced_dir) if have else None,
                     cyclic=(int(getattr(cyc, "engine_order", 1)), int(getattr(red, "cyclic_harmonics", 1))))
    nd, f_new, f_worn = m["nodal_diameter"], m["freq_new_hz"], m["freq_worn_hz"]
    family = "fixed-boundary sector" if nd is None else f"ND {nd} (harmonic 1 of the engine-order wave)"
    res = {"worn_bundle": "model", "freq_new_hz": f_new.tolist(), "freq_worn_hz": f_worn.tolist(),
           "freq_shift_hz": (f_worn - f_new).tolist(), "freq_nodal_diameter": nd, "freq_family": family,
           "reduced": REDUCED_FILE if nd is None else CYCLIC_FILE}
    log.info(f"remap: first tied frequencies of the {family}, worn − new [Hz]: "
             + ", ".join(f"{d:+.4g}" for d in res["freq_shift_hz"]))
    m["worn"].save(out / res["reduced"])
    res["reassembly_s"] = time.perf_counter() - t0
    res.update(_frf(scene, m["new"], m["worn"], out, log))
    return res


def _frf(scene, new_red, worn_red, out: Path, log) -> dict:
    """The new-vs-worn FRF's summary entries and figure (``frf_error`` if it cannot be computed)."""
    import time

    from workflow.report.remap import frf_summary, render_frf_worn_vs_new

    t1 = time.perf_counter()
    try:
        frf = worn_vs_new_frf(scene, new_red, worn_red)
    except SolverError as exc:  # e.g. no preload: no static contact state to vibrate about
        log.info(f"remap: no new-vs-worn FRF: {exc}")
        return dict(frf_peak_hz=None, frf_peak_amplitude_m=None, frf_figure=None, frf_error=str(exc))
    res = {"frf_s": time.perf_counter() - t1, **frf_summary(frf)}
    res["frf_figure"] = str(Path(render_frf_worn_vs_new(frf, out / FIG_DIR / FRF_FIGURE)).relative_to(out))
    log.info(f"remap: nonlinear FRF peak new {res['frf_peak_hz']['new']:.4g} Hz / "
             f"{res['frf_peak_amplitude_m']['new']:.4g} m, worn {res['frf_peak_hz']['worn']:.4g} Hz / "
             f"{res['frf_peak_amplitude_m']['worn']:.4g} m ({res['frf_s']:.1f} s)")
    return res


def worn_vs_new_frf(scene, new, worn, points: int | None = None) -> dict:
    """The scene's new-vs-worn FRF (:func:`workflow.engine.studies.compare.frf_new_vs_worn`):
    HBM with the scene's first Nh and nit, its contact, excitation and solver,
    ``sweep.points`` clipped to :data:`FRF_POINTS`, over ``sweep.f_start_hz``/
    ``f_stop_hz`` (else ±10 % of the new model's first excited tied mode);
    both models with the scene's contact stiffness, on the new model's penalties."""
    from workflow.engine import Variant
    from workflow.engine.studies.compare import frf_new_vs_worn
    from workflow.stages.hb import law_of, options
    from workflow.stages.reduction import contact_model

    new, worn = contact_model(new, scene["contact"]), contact_model(worn, scene["contact"])
    hb, sw = scene["hb"], scene["sweep"]
    nh = int(hb.harmonics[0])
    nit = int(hb.time_samples[0]) or 2 * nh + 1
    v = Variant("hbm", nh, max(nit, 2 * nh + 1))
    lo, hi = FRF_POINTS
    n = int(points or min(max(int(sw.points), lo), hi))
    opt, _ = options(scene)
    opt.reference, opt.eps_check_factor = None, 0.0
    return frf_new_vs_worn(new, worn, law_of(scene, new), v, (sw.f_start_hz, sw.f_stop_hz), n, opt,
                           gap=float(scene["contact"].gap))
