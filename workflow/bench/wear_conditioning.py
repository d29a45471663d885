"""How well posed the worn steady state of the ``contact-convergence`` scene is (issue 17).

``python -m workflow.bench.wear_conditioning [--grid 7x5] [--ratios 0.9999,1.0001]
[--mu 0.495,0.505] [--force 0.505] [--set SECTION.KEY=VALUE ...] [--out results/bench]``

One contact mesh of the scene (flank grid ``along x across``, meshed, assembled
and reduced as the stage does it), its worn steady state marched by the
stage's own function (pseudo-time to the worn steady state, the scene's wear
Nh, nit, penalty per unit area and tip force) once as the scene sets it and
once per change, one change at a time:

* ``frequency_ratio``: the wear excitation at that multiple of the mesh's
  first tied frequency (the scene's is 1: the tied frequency itself);
* ``contact.mu``: the friction coefficient;
* ``wear_amplitude_N``: the tip force of the wear.

``--set`` overrides a scene key in every march. The scene holds the tip at 2.5 mm
(``wear.control = "amplitude"``); ``--set 'wear.control="force"'`` wears under the fixed tip
force instead, as the runs quoted below did.

Writes ``wear_conditioning.csv`` (change, value, frequency_hz, max_wear_m,
worn_volume_m3, rel_change, steady, steps, seconds) to ``--out``; rel_change
is against the unchanged run. Measured 2026-11-27 (ae0e5f9) on 7 × 5 (70 pairs):
μ ± 1 % moves the max wear ∓0.8 %, the force + 1 % +1.4 %, the frequency
± 1e-4 ∓3.3 % (docs/contact-layout.md, "Why the worn steady state does not
converge with the contact mesh"). Each march costs ~50 s on 70 pairs.
"""
from __future__ import annotations

import argparse
import csv
import tempfile
import time
from pathlib import Path

import numpy as np

SCENE = "contact-convergence"


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",") if v.strip()]


def _march(model, overrides: list[str]) -> dict:
    """The stage's worn steady state of ``model`` under the scene with ``overrides``."""
    from workflow.scene import load_scene
    from workflow.stages.contact_convergence import _worn_profile

    scene = load_scene(SCENE, overrides)
    t0 = time.perf_counter()
    out = _worn_profile(model, scene, scene["contact_convergence"])
    W = out["W"]
    return {"frequency_hz": out["frequency_hz"], "max_wear_m": float(W.max()),
            "worn_volume_m3": float(W @ np.asarray(model.area)), "steady": out["steady"],
            "steps": out["steps"], "reason": out["reason"], "seconds": time.perf_counter() - t0}


def run(grid: tuple[int, int], ratios, mus, forces, out: Path, sets=()) -> list[dict]:
    """Rows of ``wear_conditioning.csv`` (see the module docstring); writes the file."""
    from workflow.scene import load_scene
    from workflow.stages.contact_convergence import build_model

    scene = load_scene(SCENE)
    with tempfile.TemporaryDirectory() as work:
        model, _, _ = build_model(scene, grid[0], grid[1], Path(work))
    sets = list(sets)
    base = _march(model, sets)
    rows = [{"change": "none", "value": "", **base}]
    f_tied = base["frequency_hz"]           # the scene wears at the first tied frequency
    cases = [("frequency_ratio", r, [f"wear.frequency_hz={r * f_tied!r}"]) for r in ratios]
    cases += [("contact.mu", m, [f"contact.mu={m!r}"]) for m in mus]
    cases += [("wear_amplitude_N", F, [f"contact_convergence.wear_amplitude={F!r}"]) for F in forces]
    for change, value, overrides in cases:
        r = _march(model, sets + overrides)
        rows.append({"change": change, "value": value, **r})
        print(f"{change} = {value}: max W {r['max_wear_m']:.5g} m ({r['seconds']:.0f} s)", flush=True)
    for r in rows:
        r["rel_change"] = r["max_wear_m"] / base["max_wear_m"] - 1.0
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / "wear_conditioning.csv.tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["change", "value", "frequency_hz", "max_wear_m", "worn_volume_m3",
                                           "rel_change", "steady", "steps", "reason", "seconds"])
        w.writeheader()
        w.writerows(rows)
    tmp.replace(out / "wear_conditioning.csv")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="7x5", help="flank vertices along x across (default 7x5)")
    ap.add_argument("--ratios", default="0.9999,1.0001", help="wear frequency / first tied frequency, comma-separated")
    ap.add_argument("--mu", default="0.495,0.505", help="friction coefficients, comma-separated")
    ap.add_argument("--force", default="0.505", help="wear tip forces [N], comma-separated")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="a scene override for every march (repeatable)")
    ap.add_argument("--out", default="results/bench", type=Path)
    a = ap.parse_args(argv)
    try:
        along, across = (int(v) for v in a.grid.lower().split("x"))
    except ValueError:
        ap.error(f"--grid {a.grid!r}: expected along x across, e.g. 7x5")
    run((along, across), _floats(a.ratios), _floats(a.mu), _floats(a.force), a.out, a.set)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
