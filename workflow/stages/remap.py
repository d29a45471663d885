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
  ``frf_peak_amplitude_m``, ``figures/frf_worn_vs_new.png``).

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

import csv
from pathlib import Path

import numpy as np

from workflow.errors import BundleError, GeometryError, SolverError

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


# ------------------------------------------------------------- reading inputs

def read_wear_csv(path: Path, methods=()) -> dict:
    """Columns of the wear stage's CSV: ``pair`` (int), ``position`` (p, 3) [m],
    ``W``, ``W_blade``, ``W_disk`` (p,) [m] (shares None if absent) and the
    ``method`` chosen: the first of ``methods`` with a ``W_<method>_m`` column,
    else the first W column."""
    path = Path(path)
    if not path.is_file():
        raise GeometryError(f"wear output {path} is missing (run the wear stage)")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise GeometryError(f"wear output {path} has no rows")
    cols = list(rows[0])
    w_cols = [c for c in cols if c.startswith("W_") and not c.startswith(("W_blade_", "W_disk_"))] or \
             [c for c in cols if c == "W" or c.startswith("W")]
    if not w_cols:
        raise GeometryError(f"wear output {path} has no wear-depth column (W_<method>_m)")
    chosen = next((f"W_{m}_m" for m in methods if f"W_{m}_m" in cols), w_cols[0])
    method = chosen[2:-2] if chosen.startswith("W_") and chosen.endswith("_m") else chosen

    def col(name):
        return np.array([float(r[name]) for r in rows]) if name in cols else None

    pos_cols = next(((a, b, c) for a, b, c in (("x_m", "y_m", "z_m"), ("x", "y", "z")) if a in cols), None)
    return dict(pair=np.array([int(float(r["pair"])) for r in rows]) if "pair" in cols else np.arange(len(rows)),
                position=np.column_stack([col(c) for c in pos_cols]) if pos_cols else None,
                W=col(chosen), W_blade=col(f"W_blade_{method}_m"), W_disk=col(f"W_disk_{method}_m"),
                method=method)


def pair_wear(contact, table: dict, blade_share: float):
    """:class:`geometry.remap.PairWear` in bundle pair order from the CSV table.

    Rows are matched by ``pair`` index and checked against the bundle's pair
    positions (1 µm); shares come from the CSV when present, else from
    ``blade_share``.
    """
    from geometry.remap import PairWear, wear_shares

    p = contact.n_pairs
    if contact.position is None or contact.flank is None:
        raise BundleError("the bundle's contact.npz lacks position/flank, needed to map wear onto the mesh")
    idx = table["pair"]
    if len(idx) != p or set(idx.tolist()) != set(range(p)):
        raise GeometryError(f"wear.csv has {len(idx)} rows / pairs {idx.min()}..{idx.max()}, "
                            f"the bundle {p} pairs")
    order = np.argsort(idx)
    if table["position"] is not None:
        off = np.linalg.norm(table["position"][order] - contact.position, axis=1).max()
        if off > 1e-6:
            raise GeometryError(f"wear.csv positions differ from the bundle's pairs by up to {off:.3g} m "
                                f"(was the wear computed on another bundle?)")
    W = table["W"][order]
    if table["W_blade"] is not None and table["W_disk"] is not None:
        w_blade, w_disk = table["W_blade"][order], table["W_disk"][order]
    else:
        w_blade, w_disk = wear_shares(W, blade_share)
    return PairWear(np.asarray(contact.position, float), np.asarray(contact.normal, float),
                    np.asarray(contact.flank), np.clip(w_blade, 0.0, None), np.clip(w_disk, 0.0, None))


# ------------------------------------------------------------------- the stage

def run(scene, inputs: dict, out: Path, log) -> dict:
    from geometry import remap as rm
    from reduction import dolfinx_compat as dc
    from reduction.bundle import read_bundle
    from workflow import render
    from workflow.stages.assembly import bundle_folder

    out = Path(out)
    rp, wp = scene["remap"], scene["wear"]
    bdir = bundle_folder(inputs["bundle"])
    bundle = read_bundle(bdir)
    if not (bdir / "mesh.xdmf").is_file():
        raise GeometryError(f"bundle {bdir} has no mesh.xdmf: the wear cannot be mapped onto a mesh "
                            f"(a user bundle needs its mesh for the remap stage)")
    table = read_wear_csv(Path(inputs["wear"]) / WEAR_CSV, getattr(wp, "methods", ()))
    pairs = pair_wear(bundle.contact, table, wp.blade_share)
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
    figs = [render.render_flank_wear(surfaces, out / FIG_DIR / "wear_flanks.png", rp.image_width,
                                     title=f"wear depth ({table['method']}) on each flank"),
            render.render_sector(cells, types, points, body, surfaces, out / FIG_DIR / "wear_sector.png",
                                 rp.image_width)]

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
        log.info(f"remap: figure {NAME}/{f}")
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
    """Assemble the worn model (new bundle under ``out/model``), reduce it
    (``out/reduced.npz``), compare the first tied frequencies and the nonlinear
    FRF peak of the new and the worn reduced models.

    The new reduced model is ``reduced_dir/reduced.npz`` (the reduction
    stage's) when given, else the new bundle re-reduced with the same settings.
    """
    import time

    from geometry.remap import moved
    from reduction import dolfinx_compat as dc
    from reduction.assemble import as_section, build_bundle
    from reduction.bundle import write_bundle
    from reduction.modes import frequencies

    t0 = time.perf_counter()
    meta = bundle.meta or {}
    material = scene.get("material") or as_section(meta.get("material"))
    rotation, damping, excitation = scene.get("rotation"), scene.get("damping"), scene.get("excitation")
    geometry_info = meta.get("geometry") or {}
    from reduction.assemble import DEGREE
    from reduction.pairs import contact_pairs, layout_of

    # Wear opens the gap; it does not change who touches whom. On the worn mesh
    # the flank vertices are W apart and would not match, so the pairs (DOFs,
    # frames, areas) are taken from the unworn mesh.
    unworn = contact_pairs(dc.vector_space(mesh, DEGREE), ft, nodes=layout_of(geometry_info))
    with moved(mesh, r.x):
        worn, _ = build_bundle(mesh, ct, ft, geometry_info, material, rotation, damping, excitation,
                               pairs=unworn)
        stage = out / ".worn-mesh"
        stage.mkdir(parents=True, exist_ok=True)
        dc.write_mesh_xdmf(mesh, ct, ft, stage / "mesh.xdmf")
    # Same pairs (worn positions moved along n only): match them, then carry
    # the wear into the gap so that a new wear study on this bundle starts at W = 0.
    c = worn.contact
    W = pairs.w_blade + pairs.w_disk
    match = _match_pairs(bundle.contact.position, c.position, W)
    c.gap = bundle.contact.gap + W[match]
    worn.meta = dict(worn.meta, worn_from=str(bundle.path), gap_includes_wear=True,
                     max_wear_m=float(W.max(initial=0.0)))
    write_bundle(worn, out / "model", extra_files={"mesh.xdmf": stage / "mesh.xdmf", "mesh.h5": stage / "mesh.h5"})
    stage.rmdir()
    n = min(N_FREQ, int(getattr(scene.get("modes"), "count", N_FREQ)))
    f_new, f_worn = frequencies(bundle, n, tied=True), frequencies(worn, n, tied=True)
    res = {"worn_bundle": "model", "freq_new_hz": f_new.tolist(), "freq_worn_hz": f_worn.tolist(),
           "freq_shift_hz": (f_worn - f_new).tolist(), "reduced": None}
    log.info("remap: first tied frequencies worn − new [Hz]: "
             + ", ".join(f"{d:+.4g}" for d in res["freq_shift_hz"]))
    from reduction.reduce import reduce_bundle
    from reduction.reduced import ReducedModel

    red = scene.get("reduction")
    kw = dict(n_modes=int(getattr(red, "modes", 30)))
    worn_red = reduce_bundle(worn, **kw)
    worn_red.save(out / "reduced.npz")
    res["reduced"] = "reduced.npz"
    new_path = Path(reduced_dir) / "reduced.npz" if reduced_dir is not None else None
    new_red = ReducedModel.load(new_path) if new_path is not None and new_path.is_file() else reduce_bundle(bundle, **kw)
    res["reassembly_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    try:
        frf = worn_vs_new_frf(scene, new_red, worn_red)
    except SolverError as exc:  # e.g. no preload: no static contact state to vibrate about
        log.info(f"remap: no new-vs-worn FRF: {exc}")
        res.update(frf_peak_hz=None, frf_peak_amplitude_m=None, frf_figure=None, frf_error=str(exc))
        return res
    res["frf_s"] = time.perf_counter() - t1
    res.update(frf_summary(frf))
    res["frf_figure"] = render_frf_worn_vs_new(frf, out / FIG_DIR / FRF_FIGURE)
    res["frf_figure"] = str(Path(res["frf_figure"]).relative_to(out))
    log.info(f"remap: nonlinear FRF peak new {res['frf_peak_hz']['new']:.4g} Hz / "
             f"{res['frf_peak_amplitude_m']['new']:.4g} m, worn {res['frf_peak_hz']['worn']:.4g} Hz / "
             f"{res['frf_peak_amplitude_m']['worn']:.4g} m ({res['frf_s']:.1f} s)")
    return res


# ----------------------------------------------------- new vs worn nonlinear FRF

def worn_vs_new_frf(scene, new, worn, points: int | None = None) -> dict:
    """Nonlinear FRF (HBM with the scene's first Nh and nit, its contact,
    excitation and solver) of the reduced models ``new`` and ``worn`` on one
    frequency grid around the new model's first excited tied mode
    (``sweep.f_start_hz``/``f_stop_hz``, else ±10 %), through
    :func:`workflow.engine.frf`.

    Both use the new model's DLFT penalties (sharing them keeps the
    comparison free of ε). Each model's ``gap`` is its own: the worn
    bundle's already holds W, so both run at contact-law W = 0. Returns
    ``{"freqs_hz", "new": SweepResult, "worn": ..., "tied_hz": {"new",
    "worn"}, "variant"}``; each SweepResult carries its ``static`` state.
    """
    from reduction.condense import relative_coordinates
    from workflow.contact import ContactLaw
    from workflow.engine import Variant, frf
    from workflow.engine.linear import band, first_excited_mode
    from workflow.stages.hb import law_of, options

    hb, sw, ct = scene["hb"], scene["sweep"], scene["contact"]
    nh = int(hb.harmonics[0])
    nit = int(hb.time_samples[0]) or 2 * nh + 1
    v = Variant("hbm", nh, max(nit, 2 * nh + 1))
    lo, hi = FRF_POINTS
    n = int(points or min(max(int(sw.points), lo), hi))
    rc_new = relative_coordinates(new)
    f_new, _ = first_excited_mode(rc_new)
    f0, f1 = band(sw.f_start_hz, sw.f_stop_hz, f_new)
    law0 = law_of(scene, new, rc=rc_new)
    opt, _ = options(scene)
    opt.reference, opt.eps_check_factor = None, 0.0
    out = {"freqs_hz": np.linspace(f0, f1, n), "tied_hz": {}, "variant": v}
    for key, model in (("new", new), ("worn", worn)):
        law = ContactLaw(mu=law0.mu, eps_n=law0.eps_n, eps_t=law0.eps_t,
                         gap=np.asarray(model.gap, dtype=float) + float(ct.gap))
        study = frf(model, law, [v], band_hz=(f0, f1), points=n, options=opt)
        out[key] = study.runs[0]
        out[key].static = study.static
        out["tied_hz"][key] = study.tied_hz
    return out


def _peak(r) -> tuple[float | None, float | None]:
    if not r.converged.any():
        return None, None
    a = np.where(r.converged, r.amplitude, -np.inf)
    i = int(np.argmax(a))
    return float(r.freqs_hz[i]), float(a[i])


def frf_summary(frf: dict) -> dict:
    """Summary entries of :func:`worn_vs_new_frf` (Hz, m)."""
    pk = {k: _peak(frf[k]) for k in ("new", "worn")}
    v = frf["variant"]
    return {
        "frf_peak_hz": {k: pk[k][0] for k in pk},
        "frf_peak_amplitude_m": {k: pk[k][1] for k in pk},
        "frf_tied_hz": dict(frf["tied_hz"]),
        "frf_band_hz": [float(frf["freqs_hz"][0]), float(frf["freqs_hz"][-1])],
        "frf_points": int(len(frf["freqs_hz"])),
        "frf_converged": {k: frf[k].converged_points for k in ("new", "worn")},
        "frf_variant": {"method": v.method, "harmonics": v.nh, "time_samples": v.nit},
    }


def render_frf_worn_vs_new(frf: dict, path: Path) -> Path:
    """``path`` (.png): first-harmonic tip amplitude of the new and worn models."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from workflow.io import atomic_path

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, style in (("new", "o-"), ("worn", "s--")):
        r = frf[key]
        a = np.where(r.converged, r.amplitude, np.nan)
        f_pk, a_pk = _peak(r)
        lab = f"{key}" + (f": peak {f_pk:.2f} Hz, {a_pk:.3g} m" if f_pk is not None else " (no point converged)")
        ax.plot(r.freqs_hz, a, style, ms=4, label=lab)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("tip amplitude, 1st harmonic (m)")
    ax.set_title(f"nonlinear FRF, new vs worn ({frf['variant'].label})")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path


def _match_pairs(pos_new: np.ndarray, pos_worn: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Index into the new pairs of each worn pair (nearest position; they moved by ≤ W)."""
    from scipy.spatial import cKDTree

    d, i = cKDTree(pos_new).query(pos_worn)
    if len(set(i.tolist())) != len(i) or (len(d) and d.max() > 2.0 * W.max(initial=0.0) + 1e-9):
        raise GeometryError("remap: the worn bundle's contact pairs do not match the new bundle's")
    return i
