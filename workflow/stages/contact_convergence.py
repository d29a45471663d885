"""Contact-convergence stage (issue 17): friction damping and wear against the contact mesh.

For every contact mesh of ``contact_convergence.nodes_along × nodes_across``
flank vertices (the rest of ``[geometry]`` unchanged, ``geometry.contact_nodes``
choosing vertex-only or every-node contact) the stage meshes, assembles and
reduces the sector in memory, then computes

* the friction-damped FRF peak (frequency, first-harmonic tip amplitude): a
  coarse grid of ``points`` frequencies over ± ``band`` of the first tied
  frequency brackets the maximum, a bounded scalar search
  (:func:`scipy.optimize.minimize_scalar`) refines it;
* the friction energy dissipated per cycle at the peak
  (:func:`workflow.engine.dissipation.energy_per_cycle`, on the DLFT slip path);
* the static preload state: the normal gap at the midside nodes (their
  worst interpenetration) and, for every-node contact, the same with the
  midside pairs switched off (the vertex-only layout on the same model);
* the worn profile of the pseudo-time wear (paper eq. 22) at the wear
  frequency (``wear.frequency_hz``, else the first tied frequency),
  interpolated to ``profile_points`` common points per flank.

Writes ``convergence.csv`` (one row per mesh), ``profiles.npz`` (common
points, W per mesh), ``convergence.png``, ``profiles.png`` and returns
``rows``, the relative changes between the two finest meshes
(``peak_change_last`` …) and the observed orders of convergence.

The computation is :mod:`workflow.engine.studies.meshstudy` (per mesh and over the
meshes), the common flank points :func:`geometry.flankmap.common_points`,
the figures :mod:`workflow.report.convergence`; every call into the engine
sits in the four adapters of the first section (scene → engine arguments).
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

NAME = "contact_convergence"
SECTIONS = ("geometry", "material", "rotation", "damping", "excitation", "reduction", "contact", "hb", "wear",
            "pseudotime", "contact_convergence")
NEEDS = ()
PRODUCES = ("contact_convergence",)

CSV, PROFILES = "convergence.csv", "profiles.npz"


# ------------------------------------------------------------------ engine calls

def _law(model, contact, cc, rc):
    """The scene's DLFT law on ``model`` and its ε-path (:func:`workflow.engine.studies.meshstudy.mesh_law`;
    ``cc.penalty_per_area`` > 0 sets ε per unit area, ``cc`` None: the engine's penalty)."""
    from workflow.engine.studies.meshstudy import mesh_law

    return mesh_law(model, mu=contact.mu, eps_n=contact.eps_n, eps_t=contact.eps_t, gap=contact.gap,
                    factor=contact.penalty_factor, per_area=float(cc.penalty_per_area) if cc is not None else 0.0,
                    rc=rc)


def _friction_peak(model, contact, hb, cc) -> dict:
    """:func:`workflow.engine.studies.meshstudy.friction_peak` with HBM at Nh = ``cc.harmonics``,
    nit = ``cc.time_samples`` and the scene's solver."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine import Variant
    from workflow.engine.studies.meshstudy import friction_peak

    rc = relative_coordinates(model)
    law, path = _law(model, contact, cc, rc)
    kw = dict(solver=hb.solver, tol=hb.tol, maxiter=hb.max_iterations, max_passes=contact.max_passes)
    return friction_peak(model, law, path, Variant("hbm", int(cc.harmonics), int(cc.time_samples)), band=cc.band,
                         points=int(cc.points), xtol=cc.peak_xtol, solver_kw=kw, rc=rc)


def _static_gaps(model, contact, vertex: np.ndarray) -> dict:
    """:func:`workflow.engine.studies.meshstudy.static_gaps` under the scene's contact law (engine penalty)."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.studies.meshstudy import static_gaps

    rc = relative_coordinates(model)
    law, _ = _law(model, contact, None, rc)
    return static_gaps(model, law, vertex, contact.max_passes, rc=rc)


def wear_harmonics(cc) -> int:
    """Nh of the wear marches: ``cc.wear_harmonics``, or ``cc.harmonics`` when 0."""
    return int(cc.wear_harmonics or cc.harmonics)


def wear_setup(model, scene, cc):
    """(model, law, path, options) of the stage's wear march on one contact mesh: the scene's
    contact, wear and pseudotime sections, pseudo-time only, HBM with the stage's wear Nh
    (``cc.wear_harmonics``, else ``cc.harmonics``) and nit, at the tip force
    ``cc.wear_amplitude`` when it is set."""
    from workflow.engine.condense import relative_coordinates
    from workflow.stages.wear import options

    sc = {"wear": scene["wear"], "contact": scene["contact"], "pseudotime": scene["pseudotime"],
          "hb": replace(scene["hb"], methods=["hbm"], harmonics=[wear_harmonics(cc)],
                        time_samples=[int(cc.time_samples)])}
    # the study is over the contact mesh: no ε- or Nh-check marches per mesh (each a second wear march)
    opt = replace(options(sc), methods=("pseudo-time",), eps_check_factor=0.0, nh_check=False, compare_unworn=False)
    if cc.wear_amplitude > 0:
        model = replace(model, f_harmonic=model.f_harmonic * (cc.wear_amplitude / scene["excitation"].amplitude))
    law, path = _law(model, scene["contact"], cc, relative_coordinates(model))
    return model, law, path, opt


def _worn_profile(model, scene, cc, report=None) -> dict:
    """:func:`workflow.engine.studies.meshstudy.worn_profile` of the march :func:`wear_setup` sets up;
    ``report(message)``: its progress on a long march."""
    from workflow.engine.studies.meshstudy import worn_profile

    return worn_profile(*wear_setup(model, scene, cc), report=report)


# ------------------------------------------------------------------ one contact mesh

def build_model(scene, nodes_along: int, nodes_across: int, work: Path):
    """Mesh, assemble and reduce the sector with this contact mesh.

    Returns ``(model, vertex, info)``: the :class:`ReducedModel`, the
    vertex mask of its pairs (p,) and counts (DOFs, flank area [m²]).
    """
    from geometry.sector import build_sector
    from reduction import dolfinx_compat as dc
    from reduction.assemble import DEGREE, build_bundle
    from reduction.pairs import contact_pairs
    from reduction.reduce import reduce_bundle

    gp = replace(scene["geometry"], nodes_along=int(nodes_along), nodes_across=int(nodes_across))
    msh = Path(work) / f"sector-{nodes_along}x{nodes_across}.msh"
    info = build_sector(gp, msh)
    mesh, ct, ft = dc.read_msh(msh)
    pairs = contact_pairs(dc.vector_space(mesh, DEGREE), ft, nodes=gp.contact_nodes)
    vertex = np.asarray(pairs["vertex"], bool)
    bundle, binfo = build_bundle(mesh, ct, ft, info, scene["material"], scene["rotation"], scene["damping"],
                                 scene["excitation"], pairs=pairs)
    red = scene["reduction"]
    model = reduce_bundle(bundle, n_modes=int(red.modes), cutoff_hz=float(red.cutoff_hz) or None)
    msh.unlink(missing_ok=True)
    return model, vertex, {"dofs": int(binfo["n_dofs"]), "flank_area_m2": float(binfo["flank_area_m2"])}


# ------------------------------------------------------------------ the stage

def run_level(scene, na: int, nc: int, work: Path, log) -> tuple[dict, dict]:
    """One contact mesh: its table row and its raw results (model, W)."""
    from workflow.stages.reduction import contact_model

    cc = scene["contact_convergence"]
    t0 = time.perf_counter()
    model, vertex, info = build_model(scene, na, nc, work)
    model = contact_model(model, scene["contact"])
    t_build = time.perf_counter() - t0
    t1 = time.perf_counter()
    pk = _friction_peak(model, scene["contact"], scene["hb"], cc)
    t_peak = time.perf_counter() - t1
    from workflow.engine.wear.measures import FLANK_NAMES

    static = _static_gaps(model, scene["contact"], vertex)
    flanks = static.pop("flanks")
    static.update({"static_max_pressure_pa": max(f["max_pressure_pa"] for f in flanks),
                   "static_max_lift_off_m": max(f["max_lift_off_m"] for f in flanks),
                   **{f"static_open_share_{FLANK_NAMES[f['flank']]}": f["open_share"] for f in flanks}})
    t2 = time.perf_counter()
    with_wear = cc.wear and (cc.wear_max_pairs == 0 or model.n_pairs <= cc.wear_max_pairs)
    worn = _worn_profile(model, scene, cc, report=lambda m: log.info(f"contact mesh {na}×{nc}: {m}")) \
        if with_wear else None
    t_wear = time.perf_counter() - t2
    held = ((worn or {}).get("operating_point") or {}).get("control") or {}
    L = scene["geometry"].axial_length
    row = {"nodes_along": int(na), "nodes_across": int(nc), "pairs": int(model.n_pairs),
           "h_contact_m": L / (na - 1), "dofs": info["dofs"], "tied_hz": pk["tied_hz"], "peak_hz": pk["peak_hz"],
           "peak_amplitude_m": pk["peak_amplitude_m"], "energy_J": pk["energy_J"],
           "max_wear_m": float(worn["W"].max()) if worn else None,
           # Σ W_i A_i: the worn volume, an integral of the profile (the maximum is a nodal value)
           "wear_volume_m3": float(np.dot(worn["W"], model.area)) if worn else None,
           **_wear_measures(worn),
           "wear_steady": worn["steady"] if worn else None, "wear_hz": worn["frequency_hz"] if worn else None,
           "wear_force_N": (cc.wear_amplitude or scene["excitation"].amplitude) if worn and not held else None,
           "wear_tip_amplitude_m": held.get("tip_amplitude_m") if worn and held else None,
           "area_sum_rel_err": abs(float(model.area.sum()) - info["flank_area_m2"]) / info["flank_area_m2"],
           **static, "eps_n": pk["eps_n"], "eps_t": pk["eps_t"], "peak_evaluations": pk["evaluations"], "peak_at_band_edge": pk["at_band_edge"],
           "grid_converged": pk["grid_converged"], "grid_points": len(pk["grid_hz"]),
           "build_seconds": t_build, "peak_seconds": t_peak, "wear_seconds": t_wear,
           "seconds": time.perf_counter() - t0}
    log.info(f"contact mesh {na}×{nc}: {row['pairs']} pairs, {row['dofs']} DOFs; peak {row['peak_hz']:.4f} Hz "
             f"{row['peak_amplitude_m']:.5g} m, {row['energy_J']:.5g} J/cycle"
             + (f", max wear {row['max_wear_m']:.5g} m" if worn else "")
             + f"; midside gap min {static['midside_gap_min_m']}; {row['seconds']:.1f} s "
               f"(model {t_build:.1f}, peak {t_peak:.1f}, wear {t_wear:.1f})")
    return row, {"model": model, "W": worn["W"] if worn else None, "flank_area_m2": info["flank_area_m2"]}


def _wear_measures(worn: dict | None) -> dict:
    """The table's wear measures of one mesh (:mod:`workflow.engine.wear.measures`): the ℓ-filtered
    profile's RMS and maximum over both flanks, the scar width, the energy per cycle before and
    after wear, the worn − new friction-damped resonance shift, and each flank's worn volume (the
    sum of the two can converge while each flank moves: the flanks trade wear between meshes)."""
    from workflow.engine.wear.measures import FLANK_NAMES

    flank_keys = tuple(f"worn_volume_{name}_m3" for name in FLANK_NAMES.values())
    keys = ("profile_l2_m", "filtered_max_wear_m", "scar_width_m", "wear_length_m", "energy_new_J", "energy_worn_J",
            "resonance_shift_hz", "resonance_shift_amplitude_rel", "wear_operating_point")
    if not worn or not worn.get("measures"):
        return dict.fromkeys(keys + flank_keys)
    per = worn["measures"]["flanks"]
    flanks = {k: (per[name]["worn_volume_m3"] if name in per else None)
              for k, name in zip(flank_keys, FLANK_NAMES.values())}
    fl = per.values()
    rs = worn.get("resonance_shift") or {}
    op = worn.get("operating_point") or {}
    return dict(zip(keys, (float(np.sqrt(sum(f["profile_l2_m"] ** 2 for f in fl))),
                           max(f["filtered_max_m"] for f in fl), max(f["scar_width_m"] for f in fl),
                           worn["measures"]["length_m"], worn["energy_per_cycle_J"].get("new"),
                           worn["energy_per_cycle_J"].get("worn"), rs.get("hz"), rs.get("amplitude_rel"),
                           op.get("kind") if op.get("kind") != "detuning" else f"detuning {op['detuning']:g}"))) | flanks


def unconverged(rows: list[dict]) -> list[str]:
    """The pipeline's ``unconverged`` lines (exit status 3): per contact mesh, points of
    the peak bracket that did not converge, and a wear march that did not reach its worn
    steady state (its profile is then where the march stopped, not the steady state)."""
    out = []
    for r in rows:
        if r["grid_converged"] < r["grid_points"]:
            out.append(f"{r['pairs']} pairs: {r['grid_points'] - r['grid_converged']}/{r['grid_points']} "
                       "frequencies of the peak bracket did not converge (raise hb.max_iterations)")
        if r["wear_steady"] is False:
            out.append(f"{r['pairs']} pairs: the wear march did not reach its worn steady state "
                       "(raise pseudotime.max_steps); its profile is where the march stopped")
    return out


def kept_level(scene, na: int, nc: int, work: Path, log, store) -> tuple[dict, dict]:
    """:func:`run_level`, or its row and worn profile kept by an interrupted run of the same study
    (``store``: :class:`workflow.progress.Progress` or None); a computed level is kept there."""
    from types import SimpleNamespace

    name = f"mesh-{na}x{nc}"
    got = None if store is None else store.get(name)
    if got is not None:
        log.info(f"contact mesh {na}×{nc}: kept from an interrupted run")
        model = SimpleNamespace(position=np.asarray(got["position"], float), flank=np.asarray(got["flank"]))
        return got["row"], {"model": model, "W": None if got["W"] is None else np.asarray(got["W"], float),
                            "flank_area_m2": got["flank_area_m2"]}
    row, raw = run_level(scene, na, nc, work, log)
    if store is not None:
        m = raw["model"]
        store.put(name, {"row": row, "position": np.asarray(m.position), "flank": np.asarray(m.flank),
                         "W": raw["W"], "flank_area_m2": raw["flank_area_m2"]})
    return row, raw


def run(scene, inputs: dict, out: Path, log) -> dict:
    from geometry.flankmap import common_points, profile_at
    from workflow import progress
    from workflow.engine.studies.meshstudy import summarise
    from workflow.engine.wear.measures import FLANK_NAMES
    from workflow.io import write_npz, write_rows
    from workflow.report.convergence import plot
    from workflow.stages.reduction import contact_stiffness

    out = Path(out)
    cc = scene["contact_convergence"]
    work = out / "work"
    work.mkdir(parents=True, exist_ok=True)
    rows, raws = [], []
    store = progress.current()
    for na, nc in zip(cc.nodes_along, cc.nodes_across):
        row, raw = kept_level(scene, int(na), int(nc), work, log, store)
        rows.append(row)
        raws.append(raw)
        write_rows(out / CSV, rows)  # the table grows on disk as the study runs
    work.rmdir()
    profiles = None
    m0 = raws[0]["model"]
    points, pflank = common_points(np.asarray(m0.position), np.asarray(m0.flank), cc.profile_points)
    worn = [(row, raw) for row, raw in zip(rows, raws) if raw["W"] is not None]
    if worn:
        profiles = np.array([profile_at(points, pflank, np.asarray(raw["model"].position),
                                        np.asarray(raw["model"].flank), raw["W"]) for _, raw in worn])
        write_npz(out / PROFILES, points=points, flank=pflank, W=profiles,
                  pairs=np.array([row["pairs"] for row, _ in worn]))
    summary = summarise(rows, profiles)
    figures = plot(out, rows, points, pflank, profiles)
    log.info("contact convergence, two finest meshes: "
             + ", ".join(f"{k} {v:.3%}" for k, v in summary.items() if k.endswith("change_last") and v is not None))
    for k, sp in summary["spread"].items():
        if sp is not None and sp["range_rel"] is not None:
            log.info(f"{k} over the {sp['meshes']} worn meshes: median {sp['median']:.4g}, "
                     f"{sp['min']:.4g} … {sp['max']:.4g} (range {sp['range_rel']:.1%} of the median)")
    return {"rows": [{**{k: r[k] for k in ("pairs", "peak_hz", "peak_amplitude_m", "energy_J", "max_wear_m",
                                         "profile_l2_m", "resonance_shift_hz", "seconds")},
                      "worn_volume_m3": r["wear_volume_m3"],
                      "worn_volume_flanks_m3": {n: r.get(f"worn_volume_{n}_m3") for n in FLANK_NAMES.values()}}
                     for r in rows],
            "unconverged": unconverged(rows),
            "table": rows, "layout": scene["geometry"].contact_nodes, "harmonics": int(cc.harmonics),
            "wear_harmonics": wear_harmonics(cc), "law_length_m": float(scene["wear"].length_m),
            "law_length_over": scene["wear"].length_over, "contact_stiffness": contact_stiffness(scene["contact"]),
            "time_samples": int(cc.time_samples), **summary, "csv": CSV,
            "profiles": PROFILES if profiles is not None else None, "figures": figures}
