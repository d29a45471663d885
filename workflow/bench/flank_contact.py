"""The flank contact and the held-amplitude worn state against the contact mesh (issue 48).

``python -m workflow.bench.flank_contact --grids 4x2,7x3,7x5,8x9 [--tip 2.5e-3] [--crown 0]
[--grading 1] [--set SECTION.KEY=VALUE ...] [--models DIR] [--static-only] [--out results/bench]``

For each flank grid (``along x across`` vertices) of the ``contact-convergence`` scene's sector
(meshed, assembled and reduced as the stage does it; ``--models`` keeps the reduced models
there, ``model-AxC.npz``, and reads them back):

* the static contact under the preload, per flank: the share of the flank's area open, the
  largest static lift-off [m], the largest pressure [Pa] and the normal load [N]
  (:meth:`workflow.engine.hb.HBProblem.static_state` with the scene's penalty per unit area);
* unless ``--static-only``: the worn steady state with the tip held at ``--tip`` [m]
  (``wear.control = "amplitude"``) at the mesh's first tied frequency — the stage's own march
  (:func:`workflow.stages.contact_convergence._worn_profile`), no resonance-shift search.

``--set`` overrides scene keys; ``contact.stiffness_n``/``stiffness_t`` give every grid's model the
interface layer of :mod:`reduction.layer` before both the static state and the march.

``--crown`` δ [m] adds a parabolic initial gap across each flank (δ at its long edges, 0 on
its centre line): a crowned flank, as micro-geometry. ``--grading`` g < 1 crowds the vertices
across each flank towards its long edges (``geometry.flank_grading``).

Writes ``flank_contact.csv`` (one row per grid and flank) to ``--out``, and each worn state
(W, the pairs' position, flank and area) to ``worn-AxC.npz``.
"""
from __future__ import annotations

import argparse
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
    from reduction.reduced import ReducedModel
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


def static_contact(model, scene) -> list[dict]:
    """Per flank: :func:`workflow.engine.studies.meshstudy.flank_bearing` under the scene's law
    (penalty per unit area)."""
    from reduction.condense import relative_coordinates
    from workflow.engine.studies.meshstudy import flank_bearing
    from workflow.engine.studies.wearstudy import build_problem
    from workflow.stages.contact_convergence import _law
    from workflow.stages.wear import options

    rc = relative_coordinates(model)
    law, _ = _law(model, scene["contact"], scene["contact_convergence"], rc)
    sc = {"wear": scene["wear"], "contact": scene["contact"], "pseudotime": scene["pseudotime"],
          "hb": replace(scene["hb"], methods=["hbm"], harmonics=[1], time_samples=[8])}
    st = build_problem(model, law, options(sc), rc=rc)[0].static
    return flank_bearing(model, st, np.asarray(law.gap, float))


def worn(model, tip: float, sets=()) -> dict:
    """The held-amplitude worn steady state by the stage's march (``sets``: more scene overrides)."""
    from workflow.scene import load_scene
    from workflow.stages.contact_convergence import _worn_profile

    scene = load_scene(SCENE, ["wear.control=\"amplitude\"", f"wear.tip_amplitude_m={tip!r}",
                               "wear.resonance_shift=false", *sets])
    t0 = time.perf_counter()
    out = _worn_profile(model, scene, scene["contact_convergence"])
    W = out["W"]
    return {"max_wear_m": float(W.max()), "worn_volume_m3": float(W @ np.asarray(model.area)),
            "steady": out["steady"], "steps": out["steps"], "reason": out["reason"], "seconds": time.perf_counter() - t0, "W": W}


def run(grids, tip: float, crown: float, keep: Path | None, static_only: bool, out: Path,
        grading: float = 1.0, sets=()) -> list[dict]:
    from workflow.engine.wear.measures import worn_volume
    from workflow.scene import load_scene
    from workflow.stages.reduction import contact_model

    scene = load_scene(SCENE, [f"geometry.flank_grading={grading!r}", *sets])
    rows = []
    out.mkdir(parents=True, exist_ok=True)
    for g in grids:
        model = contact_model(model_of(scene, g, keep), scene["contact"])
        if crown > 0:
            model = replace(model, gap=np.asarray(model.gap, float) + crown_gap(model, crown))
        w = {} if static_only else worn(model, tip, sets)
        per_flank = {}
        if w:
            W = w.pop("W")
            per_flank = worn_volume(W, model.area, model.flank)
            np.savez(out / f"worn-{g[0]}x{g[1]}.npz", W=W, position=model.position, flank=model.flank,
                     area=model.area)
        for r in static_contact(model, scene):
            rows.append({"grid": f"{g[0]}x{g[1]}", "pairs": int(model.area.size), "crown_m": crown,
                         "flank_grading": grading, **r,
                         "tip_amplitude_m": None if static_only else tip, **w,
                         "flank_worn_volume_m3": per_flank.get(r["flank"])})
        print(rows[-1], flush=True)
    from workflow.io import write_rows

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
    ap.add_argument("--out", default="results/bench", type=Path)
    a = ap.parse_args(argv)
    try:
        grids = [tuple(int(v) for v in g.lower().split("x")) for g in a.grids.split(",") if g.strip()]
    except ValueError:
        ap.error(f"--grids {a.grids!r}: expected e.g. 4x2,7x3")
    if not (a.tip > 0 and a.crown >= 0 and 0 < a.grading <= 1):
        ap.error("--tip must be > 0, --crown ≥ 0 and --grading in (0, 1]")
    run(grids, a.tip, a.crown, a.models, a.static_only, a.out, a.grading, a.set)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
