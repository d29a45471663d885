"""The flank contact and the held-amplitude worn state against the contact mesh (issue 48).

``python -m workflow.bench.flank_contact --grids 4x2,7x3,7x5,8x9 [--tip 2.5e-3] [--crown 0]
[--grading 1] [--set SECTION.KEY=VALUE ...] [--models DIR] [--static-only] [--worn DIR] [--shift]
[--response R1,R2,...] [--sample S] [--out results/bench]``

For each flank grid (``along x across`` vertices) of the ``contact-convergence`` scene's sector
(meshed, assembled and reduced as the stage does it; ``--models`` keeps the reduced models
there, ``model-AxC.npz``, and reads them back):

* the static contact under the preload, per flank: the share of the flank's area open, the
  largest static lift-off [m], the largest pressure [Pa] and the normal load [N]
  (:meth:`workflow.engine.hb.HBProblem.static_state` with the scene's penalty per unit area);
* unless ``--static-only``: the worn steady state with the tip held at ``--tip`` [m]
  (``wear.control = "amplitude"``) at the mesh's first tied frequency — the stage's own march
  (:func:`workflow.stages.contact_convergence._worn_profile`), no resonance-shift search;
  with ``--worn DIR`` the worn states a previous run wrote there (``worn-AxC.npz``) instead;
* with ``--shift``, per worn state: the worn − new friction-damped resonance
  (:func:`workflow.engine.studies.operating.resonance_shift` on the stage's march setup,
  :func:`workflow.stages.contact_convergence.wear_setup`), and how each flank bears under the
  preload once worn (the worn depth in the gap) beside its wear scar (pairs at ≥ 5 % of the
  deepest; :func:`workflow.engine.wear.measures.scar`).

With ``--response`` r₁,r₂,… the bench gives instead, per grid, the wear response curve
(:func:`workflow.engine.studies.wearresponse.wear_response` on the stage's march setup): the worn
steady state at each r × the grid's own friction-damped resonance, under the scene's 0.5 N tip
force (``--set 'wear.control="force"'``) or with the tip held at ``--tip``; ``wear_response.csv``
(one row per grid and point, with the ℓ-filtered profile's L2 over both flanks) and each point's
worn depth in ``response-AxC.npz`` (``W`` (r, p) [m], ``detunings``); with ``--shift`` each
point's worn friction-damped resonance and the detuning the worn blade sees (``worn_detuning``),
and then ``wear.response_refine`` bisections of the curve's cliff (rows ``refined``).

``--set`` overrides scene keys; ``contact.stiffness_n``/``stiffness_t`` give every grid's model the
interface layer of :mod:`reduction.layer` before both the static state and the march; with
``--sample S`` that layer and the contact law sit at S² points a contact-surface triangle
(:func:`reduction.layer.with_sampled_layer`), and the rows' pairs are those points.

``--crown`` δ [m] adds a parabolic initial gap across each flank (δ at its long edges, 0 on
its centre line): a crowned flank, as micro-geometry. ``--grading`` g < 1 crowds the vertices
across each flank towards its long edges (``geometry.flank_grading``).

Writes ``flank_contact.csv`` (one row per grid and flank; with a worn state, the flank's worn
volume, ℓ-filtered profile RMS and maximum at ``wear.measure_length_m`` and scar width) to
``--out``, and each worn state
(W, the pairs' position, flank and area, and the march's path: ``cycles`` (k,), ``W_history``
(k, p) [m]) to ``worn-AxC.npz``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

SCENE = "contact-convergence"


def crown_gap(model, delta: float) -> np.ndarray:
    """A parabolic initial gap (p,) [m] across each flank: δ (d/b)², d the distance from the
    flank's centre line across it (in the y–z plane), b its half width."""
    pos, fl = np.asarray(model.position, float), np.asarray(model.flank)
    g = np.zeros(fl.size)
    for f in np.unique(fl):
        idx = np.flatnonzero(fl == f)
        q = pos[idx, 1:] - pos[idx, 1:].mean(0)
        d = q @ np.linalg.svd(q, full_matrices=False)[2][0]
        c, b = 0.5 * (d.max() + d.min()), 0.5 * (d.max() - d.min())
        g[idx] = delta * ((d - c) / b) ** 2
    return g


def model_of(scene, grid: tuple[int, int], keep: Path | None):
    """The reduced model of ``grid``, built by the stage's :func:`build_model` (or read from ``keep``)."""
    from workflow.engine.model import ReducedModel
    from workflow.stages.contact_convergence import build_model

    g = scene["geometry"].flank_grading
    name = f"model-{grid[0]}x{grid[1]}" + (f"-g{g:g}" if g < 1 else "")
    path = None if keep is None else keep / f"{name}.npz"
    if path is not None and path.exists():
        return ReducedModel.load(path)
    with tempfile.TemporaryDirectory() as work:
        model, _, _ = build_model(scene, grid[0], grid[1], Path(work))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        model.save(path)
    return model


def sampled_model(model, contact, per_side: int):
    """``model`` with the scene's interface layer integrated at ``per_side``² points a surface
    triangle (:func:`reduction.layer.with_sampled_layer`) instead of at its node pairs."""
    from reduction.layer import with_sampled_layer

    if not (contact.stiffness_n > 0 and contact.stiffness_t > 0):
        raise SystemExit("--sample needs an interface layer: --set contact.stiffness_n=K --set contact.stiffness_t=K")
    return with_sampled_layer(model, contact.stiffness_n, contact.stiffness_t, per_side)


def saved_worn(path: Path, model) -> np.ndarray:
    """W (p,) [m] of a worn state this bench wrote (``worn-AxC.npz``), refused unless its pairs are
    ``model``'s (the same positions)."""
    if not path.exists():
        raise SystemExit(f"--worn: no worn state {path}")
    with np.load(path) as z:
        W, pos = np.asarray(z["W"], float), np.asarray(z["position"], float)
    if pos.shape != np.shape(model.position) or not np.allclose(pos, model.position, rtol=0, atol=1e-9):
        raise SystemExit(f"--worn: {path} holds other pairs than this grid's model")
    return W


def static_contact(model, scene, W=None) -> list[dict]:
    """Per flank: :func:`workflow.engine.studies.meshstudy.flank_bearing` under the scene's law
    (penalty per unit area), with the worn depth W (p,) [m] in the gap when given."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.studies.meshstudy import flank_bearing
    from workflow.engine.studies.wearstudy import build_problem
    from workflow.stages.contact_convergence import _law
    from workflow.stages.wear import options

    rc = relative_coordinates(model)
    law, _ = _law(model, scene["contact"], scene["contact_convergence"], rc)
    if W is not None:
        law = law.with_wear(np.maximum(np.asarray(W, float), 0.0))
    sc = {"wear": scene["wear"], "contact": scene["contact"], "pseudotime": scene["pseudotime"],
          "hb": replace(scene["hb"], methods=["hbm"], harmonics=[1], time_samples=[8])}
    st = build_problem(model, law, options(sc), rc=rc)[0].static
    return flank_bearing(model, st, np.asarray(law.gap, float) + np.asarray(law.wear, float))


def worn(model, tip: float, sets=()) -> dict:
    """The held-amplitude worn steady state by the stage's march (``sets``: more scene overrides)."""
    from workflow.stages.contact_convergence import _worn_profile

    scene = _scene(tip, sets)
    t0 = time.perf_counter()
    out = _worn_profile(model, scene, scene["contact_convergence"],
                        report=lambda m: print(m, file=sys.stderr, flush=True))
    W = out["W"]
    return {"max_wear_m": float(W.max()), "worn_volume_m3": float(W @ np.asarray(model.area)),
            "steady": out["steady"], "steps": out["steps"], "reason": out["reason"], "seconds": time.perf_counter() - t0,
            # the unworn vibration's friction energy per cycle [J]: k_w/μ times it is the worn volume's first rate
            "energy_new_J": (out["energy_per_cycle_J"] or {}).get("new"), "W": W,
            "path": {"cycles": out["cycles"], "W_history": out["W_history"]}}


def _scene(tip: float, sets=()):
    from workflow.scene import load_scene

    return load_scene(SCENE, ["wear.control=\"amplitude\"", f"wear.tip_amplitude_m={tip!r}",
                              "wear.resonance_shift=false", *sets])


def worn_state(model, W, tip: float, sets=()) -> dict:
    """What a worn state W (p,) [m] does (``--shift``): ``shift`` the worn − new friction-damped
    resonance of the stage's march setup (Nh, nit, law) under the scene's force, and per flank
    ``flanks[f]``: the share of its area open under the preload once worn and its largest worn
    pressure [Pa]."""
    from workflow.engine.studies.operating import resonance_shift
    from workflow.stages.contact_convergence import wear_setup

    scene = _scene(tip, sets)
    m, law, _, opt = wear_setup(model, scene, scene["contact_convergence"])
    t0 = time.perf_counter()
    shift = resonance_shift(m, law, W, opt)
    shift["seconds"] = time.perf_counter() - t0
    bearing = {r["flank"]: r for r in static_contact(model, scene, W)}
    flanks = {f: {"worn_open_share": bearing[f]["open_share"],
                  "worn_max_pressure_pa": bearing[f]["max_pressure_pa"]} for f in bearing}
    return {"shift": shift, "flanks": flanks}


def response(model, tip: float, sets, detunings, ell: float, shift: bool = False) -> list[dict]:
    """The wear response curve of one grid's model (``--response``): one row per point, the
    engine's row (:func:`~workflow.engine.studies.wearresponse.wear_response`, its worn depth
    ``W`` kept; with ``shift`` each worn state's friction-damped resonance) with the grid's
    friction-damped resonance and the ℓ-filtered profile's L2 over both flanks [m] (the root sum
    of the flanks' RMS, as :mod:`workflow.bench.flank_convergence` takes it) and its largest depth."""
    from workflow.engine.studies.wearresponse import wear_response
    from workflow.engine.wear.measures import wear_measures
    from workflow.stages.contact_convergence import wear_setup

    scene = _scene(tip, sets)
    m, law, _, opt = wear_setup(model, scene, scene["contact_convergence"])
    res = wear_response(m, law, replace(opt, resonance_shift=shift), detunings, keep_states=True,
                        report=lambda msg: print(msg, file=sys.stderr, flush=True),
                        refine=scene["wear"].response_refine)
    rows = []
    for r in res["rows"]:
        fl = wear_measures(r["W"], model.position, model.area, model.flank, ell)["flanks"].values()
        rows.append({"resonance_hz": res["resonance_hz"], "control": opt.control, **r,
                     "profile_l2_m": float(np.sqrt(sum(f["profile_l2_m"] ** 2 for f in fl))),
                     "filtered_max_m": max(f["filtered_max_m"] for f in fl)})
    return rows


def grid_model(scene, grid: tuple[int, int], keep: Path | None, crown: float, sample: int):
    """The model the bench studies on ``grid``: the scene's interface layer at the node pairs, or at
    ``sample``² points a surface triangle when ``sample`` > 0, and a crown of ``crown`` [m]."""
    from workflow.stages.reduction import contact_model

    raw = model_of(scene, grid, keep)
    model = sampled_model(raw, scene["contact"], sample) if sample else contact_model(raw, scene["contact"])
    if crown > 0:
        model = replace(model, gap=np.asarray(model.gap, float) + crown_gap(model, crown))
    return model


def _measure_columns(W, model, ell: float) -> dict:
    """Per flank code, its row columns of the worn state W (p,) [m]
    (:func:`workflow.engine.wear.measures.wear_measures` at the scene's ``wear.measure_length_m`` ℓ):
    worn volume [m³], the ℓ-filtered profile's RMS and largest depth [m], the scar's area [m²] and
    width [m]."""
    from workflow.engine.wear.measures import FLANK_NAMES, wear_measures

    m = wear_measures(W, model.position, model.area, model.flank, ell)
    return {code: {"flank_worn_volume_m3": f["worn_volume_m3"], "measure_length_m": m["length_m"],
                   "profile_l2_m": f["profile_l2_m"], "filtered_max_m": f["filtered_max_m"],
                   "scar_area_m2": f["scar_area_m2"], "scar_width_m": f["scar_width_m"]}
            for code, name in FLANK_NAMES.items() if (f := m["flanks"].get(name))}


def _shift_columns(state: dict, flank: int) -> dict:
    """One flank's row columns of :func:`worn_state` (none without ``--shift``)."""
    if not state:
        return {}
    sh = state["shift"]
    return {**state["flanks"][flank], "new_hz": sh.get("new_hz"), "worn_hz": sh.get("worn_hz"),
            "resonance_shift_rel": sh.get("rel"), "amplitude_shift_rel": sh.get("amplitude_rel"),
            "shift_seconds": sh["seconds"], "shift_reason": sh.get("reason")}


def run(grids, tip: float, crown: float, keep: Path | None, static_only: bool, out: Path,
        grading: float = 1.0, sets=(), worn_from: Path | None = None, shift: bool = False,
        sample: int = 0, detunings=()) -> list[dict]:
    from workflow.io import write_npz, write_rows
    from workflow.scene import load_scene

    scene = load_scene(SCENE, [f"geometry.flank_grading={grading!r}", *sets])
    rows = []
    out.mkdir(parents=True, exist_ok=True)
    for g in grids:
        model = grid_model(scene, g, keep, crown, sample)
        if detunings:
            curve = response(model, tip, sets, detunings, scene["wear"].measure_length_m, shift)
            write_npz(out / f"response-{g[0]}x{g[1]}.npz", W=np.stack([r.pop("W") for r in curve]),
                      detunings=np.array([r["detuning"] for r in curve]), position=model.position,
                      flank=model.flank, area=model.area)
            rows += [{"grid": f"{g[0]}x{g[1]}", "pairs": int(model.area.size), **r} for r in curve]
            write_rows(out / "wear_response.csv", rows)
            print(rows[-1], flush=True)
            continue
        name = f"worn-{g[0]}x{g[1]}.npz"
        if worn_from is not None:
            W = saved_worn(worn_from / name, model)
            w = {"max_wear_m": float(W.max()), "worn_volume_m3": float(W @ np.asarray(model.area)), "W": W}
        else:
            w = {} if static_only else worn(model, tip, sets)
        per_flank, state = {}, {}
        if w:
            W, path = w.pop("W"), w.pop("path", {})
            per_flank = _measure_columns(W, model, scene["wear"].measure_length_m)
            if worn_from is None:
                write_npz(out / name, W=W, position=model.position, flank=model.flank, area=model.area, **path)
            if shift:
                state = worn_state(model, W, tip, sets)
        for r in static_contact(model, scene):
            rows.append({"grid": f"{g[0]}x{g[1]}", "pairs": int(model.area.size), "crown_m": crown,
                         "flank_grading": grading, **r, "tip_amplitude_m": None if static_only else tip, **w,
                         **per_flank.get(r["flank"], {}), **_shift_columns(state, r["flank"])})
        print(rows[-1], flush=True)
    if not detunings:
        write_rows(out / "flank_contact.csv", rows)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grids", default="4x2,7x3,7x5", help="flank grids along x across, comma-separated")
    ap.add_argument("--tip", type=float, default=2.5e-3, help="held tip amplitude [m]")
    ap.add_argument("--crown", type=float, default=0.0, help="flank crown δ [m] (0: flat flanks)")
    ap.add_argument("--grading", type=float, default=1.0,
                    help="geometry.flank_grading: < 1 crowds the vertices towards the flanks' long edges")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="a scene override, e.g. wear.length_m=0.002, or contact.stiffness_n=1e14 (an interface "
                         "layer on every grid's model, static state and march alike) (repeatable)")
    ap.add_argument("--models", type=Path, default=None, help="keep the reduced models in this folder")
    ap.add_argument("--static-only", action="store_true", help="the static contact only, no wear march")
    ap.add_argument("--worn", type=Path, default=None,
                    help="read each grid's worn state (worn-AxC.npz) from this folder instead of marching")
    ap.add_argument("--shift", action="store_true",
                    help="per worn state: the worn − new friction-damped resonance and the worn flanks' bearing "
                         "(with --response: each point's worn resonance)")
    ap.add_argument("--response", default="", metavar="R1,R2,...",
                    help="per grid, the wear response curve at these f / f_r (f_r the grid's friction-damped "
                         "resonance) instead of one held-amplitude march")
    ap.add_argument("--sample", type=int, default=0, metavar="S",
                    help="integrate the interface layer at S² points a contact-surface triangle instead of at "
                         "the node pairs (needs contact.stiffness_n, stiffness_t > 0)")
    ap.add_argument("--out", default="results/bench", type=Path)
    a = ap.parse_args(argv)
    try:
        grids = [tuple(int(v) for v in g.lower().split("x")) for g in a.grids.split(",") if g.strip()]
    except ValueError:
        ap.error(f"--grids {a.grids!r}: expected e.g. 4x2,7x3")
    if not (a.tip > 0 and a.crown >= 0 and 0 < a.grading <= 1):
        ap.error("--tip must be > 0, --crown ≥ 0 and --grading in (0, 1]")
    if a.static_only and (a.worn or a.shift):
        ap.error("--static-only has no worn state for --worn or --shift")
    if a.sample < 0:
        ap.error("--sample must be ≥ 0")
    try:
        detunings = [float(r) for r in a.response.split(",") if r.strip()]
    except ValueError:
        ap.error(f"--response {a.response!r}: expected f / f_r values, e.g. 0.995,1,1.005")
    if any(not 0.5 <= r <= 2.0 for r in detunings):
        ap.error("--response: each f / f_r must lie within 0.5–2")
    if detunings and (a.static_only or a.worn):
        ap.error("--response marches its own worn states: not with --static-only or --worn")
    run(grids, a.tip, a.crown, a.models, a.static_only, a.out, a.grading, a.set, a.worn, a.shift, a.sample,
        detunings)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
