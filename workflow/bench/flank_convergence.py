"""How the held-amplitude worn state converges along a refinement of the contact grid (issue 48).

``python -m workflow.bench.flank_convergence DIR [DIR ...] [--out OUT]``

Each ``DIR`` holds a ``flank_contact.csv`` of :mod:`workflow.bench.flank_contact` (one grid a
folder or several; ``--shift`` runs add the worn − new resonance), or a ``wear_response.csv`` of
its ``--response`` runs, or both. The meshes are ordered by
their pairs and the mesh size is h ∝ pairs^(-1/2) (the flanks' area is the same on every grid),
so the folders should hold one cell shape refined — grids of different shapes at one pair count
measure the cells' shape, not their size. Per measure:

* the value on every mesh, the relative change between the two finest
  (:func:`workflow.engine.studies.meshstudy.rel_change`) and their difference (for the
  resonance shift, itself relative to the frequency, the difference is the measure);
* the observed order of the three finest and Roache's grid-convergence index of the finest
  (:func:`~workflow.engine.studies.meshstudy.observed_order`,
  :func:`~workflow.engine.studies.meshstudy.grid_convergence_index`; none where the changes
  are not monotone).

The measures: the worn volume (both flanks, and each), the node-wise max depth, the max depth
at least ``--end-band`` [m] from the flanks' axial ends (the slot's end faces cut the contact
there: a corner of the contact, whose depth is a point value), the ℓ-filtered profile's RMS and
maximum on each flank and over both (``profile_l2_m``: the root sum of the flanks' squares), and,
with ``--shift`` rows, the worn − new resonance (relative). From a wear response curve: the worn
volume, node-wise max depth, ℓ-filtered profile's L2 and (``--shift`` runs) the detuning the worn
blade sees at each f / f_r every mesh has (``response_worn_volume_m3@1`` …), and the curve's peak — the largest worn volume of a worn steady
state over its points (``response_peak_volume_m3``) and where it lies (``response_peak_detuning``),
with the cliff's bracket (``response_cliff_low``, ``response_cliff_high``:
:func:`workflow.engine.studies.wearresponse.cliff`; a bisection's points enter the peak and the
bracket only, being their own mesh's).

Writes ``flank_convergence.csv`` (one row a mesh) and ``flank_convergence.json`` (per measure:
values, ``change_last``, ``observed_order``, ``gci``) to ``--out``, and with response curves
``wear_response_meshes.png`` (every mesh's curve).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

#: Per-flank measures of one mesh: (name, column of flank_contact.csv); ``name_flank0``, ``name_flank1``
PER_FLANK = (("profile_l2_m", "profile_l2_m"), ("filtered_max_m", "filtered_max_m"),
             ("worn_volume_m3", "flank_worn_volume_m3"))


def _float(v):
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if np.isfinite(x) else None


#: Measures of a wear response curve's point: (name, column of wear_response.csv)
RESPONSE = (("response_worn_volume_m3", "worn_volume_m3"), ("response_max_wear_m", "max_wear_m"),
            ("response_profile_l2_m", "profile_l2_m"), ("response_worn_detuning", "worn_detuning"))


def read_curves(folders) -> dict:
    """{(grid, pairs): rows} of every wear_response.csv in the folders (csv rows as read): one
    grid's points may come from several folders, a finer sampling run apart."""
    curves = {}
    for folder in map(Path, folders):
        path = folder / "wear_response.csv"
        if path.is_file():
            with open(path, newline="") as fh:
                for r in csv.DictReader(fh):
                    curves.setdefault((r["grid"], int(r["pairs"])), []).append(r)
    return curves


def figure_curves(curves: dict) -> dict:
    """:func:`read_curves`' rows as {"<pairs> pairs": rows} of numbers, for the figure."""
    return {f"{pairs} pairs": [{"detuning": float(r["detuning"]), "steady": r.get("steady") == "True",
                                "worn_volume_m3": _float(r.get("worn_volume_m3")),
                                "max_wear_m": _float(r.get("max_wear_m"))} for r in rows]
            for (_, pairs), rows in sorted(curves.items(), key=lambda kv: kv[0][1])}


def response_measures(rows: list[dict]) -> dict:
    """One mesh's wear response curve (its wear_response.csv rows) as measures: each point's
    (``name@r``) and the curve's peak — the largest worn volume of a worn steady state and its
    f / f_r (none when no point reached one)."""
    from workflow.engine.studies.wearresponse import cliff

    out = {}
    for r in rows:
        if r.get("refined") != "True":          # a bisection's point is its own mesh's: no other has it
            for name, col in RESPONSE:
                out[f"{name}@{float(r['detuning']):g}"] = _float(r.get(col))
    steady = [r for r in rows if r.get("steady") == "True" and _float(r.get("worn_volume_m3")) is not None]
    top = max(steady, key=lambda r: _float(r["worn_volume_m3"]), default=None)
    out["response_peak_volume_m3"] = None if top is None else _float(top["worn_volume_m3"])
    out["response_peak_detuning"] = None if top is None else _float(top["detuning"])
    bracket = cliff([{"detuning": float(r["detuning"]), "worn_detuning": _float(r.get("worn_detuning")),
                      "worn_volume_m3": _float(r.get("worn_volume_m3")), "steady": r.get("steady") == "True"}
                     for r in rows])
    out["response_cliff_low"], out["response_cliff_high"] = bracket or (None, None)
    return out


def mesh_rows(folders, end_band: float) -> list[dict]:
    """One dict a mesh (sorted by pairs) from the folders' flank_contact.csv and worn-AxC.npz,
    and their wear_response.csv."""
    meshes = {}
    for folder in map(Path, folders):
        path = folder / "flank_contact.csv"
        if not (path.is_file() or (folder / "wear_response.csv").is_file()):
            raise SystemExit(f"flank_convergence: no flank_contact.csv or wear_response.csv in {folder}")
        if not path.is_file():
            continue
        with open(path, newline="") as fh:
            for r in csv.DictReader(fh):
                m = meshes.setdefault(r["grid"], {"grid": r["grid"], "pairs": int(r["pairs"])})
                m.update({"worn_volume_m3": _float(r["worn_volume_m3"]), "max_wear_m": _float(r["max_wear_m"]),
                          "folder": str(folder)})
                f = int(r["flank"])
                for name, col in PER_FLANK:
                    m[f"{name}_flank{f}"] = _float(r.get(col))
                if r.get("resonance_shift_rel") not in (None, ""):
                    m["resonance_shift_rel"] = _float(r["resonance_shift_rel"])
    for (grid, pairs), rows in read_curves(folders).items():
        meshes.setdefault(grid, {"grid": grid, "pairs": pairs}).update(response_measures(rows))
    for m in meshes.values():
        if "folder" not in m:           # a response curve only: no held-amplitude worn state
            continue
        worn = Path(m["folder"]) / f"worn-{m['grid']}.npz"
        if worn.is_file():
            with np.load(worn) as z:
                W, x = z["W"], z["position"][:, 0]
            inner = (x >= x.min() + end_band - 1e-12) & (x <= x.max() - end_band + 1e-12)
            m["inner_max_wear_m"] = float(W[inner].max()) if inner.any() else None
        l2 = [m.get(f"profile_l2_m_flank{f}") for f in (0, 1)]
        fmax = [m.get(f"filtered_max_m_flank{f}") for f in (0, 1)]
        # the profile's L2 over both flanks (each flank's RMS is over its own area, which every grid shares)
        m["profile_l2_m"] = float(np.hypot(*l2)) if None not in l2 else None
        m["filtered_max_m"] = max(fmax) if None not in fmax else None
    return sorted(meshes.values(), key=lambda m: m["pairs"])


def summary(rows: list[dict]) -> dict:
    """Per measure: values, the change between the two finest, observed order and GCI."""
    from workflow.engine.studies.meshstudy import grid_convergence_index, observed_order, rel_change

    h = [m["pairs"] ** -0.5 for m in rows]
    keys = sorted({k for m in rows for k in m} - {"grid", "pairs", "folder"})
    out = {}
    for k in keys:
        q = [m.get(k) for m in rows]
        out[k] = {"values": q, "change_last": rel_change(q[-2], q[-1]) if len(q) > 1 else None,
                  # the resonance shift is itself relative (Δf/f): the bound is on its difference
                  "difference_last": q[-1] - q[-2] if len(q) > 1 and None not in q[-2:] else None,
                  "observed_order": observed_order(h, q) if None not in q[-3:] else None,
                  "gci": grid_convergence_index(h, q) if None not in q[-3:] else None}
    return {"pairs": [m["pairs"] for m in rows], "grids": [m["grid"] for m in rows], "measures": out}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", help="folders holding flank_contact.csv (and worn-AxC.npz)")
    ap.add_argument("--end-band", type=float, default=0.002,
                    help="[m] the inner max depth leaves out pairs this close to the flanks' axial ends")
    ap.add_argument("--out", default="results/bench")
    a = ap.parse_args(argv)
    from workflow.io import write_json, write_rows

    rows = mesh_rows(a.folders, a.end_band)
    if len(rows) < 2:
        ap.error("needs at least two meshes")
    out = Path(a.out)
    keys = sorted({k for m in rows for k in m if k != "folder"}, key=lambda k: (k not in ("grid", "pairs"), k))
    write_rows(out / "flank_convergence.csv", [{k: m.get(k, "") for k in keys} for m in rows])
    s = summary(rows)
    write_json(out / "flank_convergence.json", s)
    curves = read_curves(a.folders)
    if curves:
        from workflow.report.wear import plot_wear_response_meshes

        plot_wear_response_meshes(out / "wear_response_meshes.png", figure_curves(curves))
    for k, v in s["measures"].items():
        order = "—" if v["observed_order"] is None else f"{v['observed_order']:.2f}"
        gci = "—" if v["gci"] is None else f"{v['gci']:.2%}"
        change = "—" if v["change_last"] is None else f"{v['change_last']:.2%} ({v['difference_last']:+.3g})"
        print(f"{k:28s} " + " ".join("—" if x is None else f"{x:.4g}" for x in v["values"])
              + f" | last change {change}, order {order}, GCI {gci}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
