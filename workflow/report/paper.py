"""The paper's numbers beside ours (Salles et al. 2012), and what each figure shows.

Paper values are copied from the reference text
(/work/shared/reference/salles-2012-dual-time-stepping-hb-fretting-wear.md):
Table 1 (§5.1, CPU time of 50 frequencies normalised by HBM, Nh = 1,
nit = 105) and the §5.2 CPU share of the pseudo-time method (29 % of the
implicit DLFT march). Ours come from the run: the hb stage's
``cpu_table.csv`` and the wear stage's ``cpu_ratio_pseudo_over_reference``.
"""
from __future__ import annotations

#: Paper Table 1: normalised CPU per (Nh, column); columns as in the paper.
TABLE1_COLUMNS = (("hbm", "105"), ("hbm", "2Nh+1"), ("tcm", "105"), ("tcm", "2Nh+1"), ("hdhb", "2Nh+1"))
#: As printed in the paper (the report quotes these strings, not a rounding of them).
TABLE1_TEXT = {1: ("1", "0.17", "1.43", "0.18", "0.17"),
               3: ("3.71", "0.51", "2.70", "0.45", "0.71"),
               7: ("14.59", "6.41", "7.10", "3.24", "3.71"),
               17: ("521", "88.44", "44.62", "46.60", "46.70")}
TABLE1 = {nh: tuple(float(v) for v in row) for nh, row in TABLE1_TEXT.items()}
#: Paper §5.2: pseudo-time CPU / implicit DLFT CPU to the worn steady state.
CPU_RATIO_52 = 0.29
PAPER_SCENES = ("paper-frf", "paper-wear")

#: Figure file (stem) → (what to look at, the paper's figure it corresponds to or "").
CAPTIONS = {
    "frf_nh": ("Tip amplitude (first harmonic) against frequency for each method and nit; grey dash-dot: "
               "the tied and sliding linear limits. Look at how far the friction-damped peak sits below the tied "
               "peak and between the two limits, and whether the methods agree.", "Figs. 4–5"),
    # The paper's own groups: Fig. 4 is Nh = 1, 3 and Fig. 5 is Nh = 7, 17 (paper-frf's harmonics).
    "frf_nh1_3": ("Tip amplitude (first harmonic) against frequency, Nh = 1 and 3, each method and nit; grey "
                  "dash-dot: the tied and sliding linear limits. Look at how far the friction-damped peak sits below "
                  "the tied peak, and where nit = 2Nh+1 (and HDHB) part from nit = 105.", "Fig. 4"),
    "frf_nh7_17": ("The same at Nh = 7 and 17: the methods should now overlay (HDHB has converged to HBM).",
                   "Fig. 5"),
    "frf_nit_aliasing": ("The same at the lowest Nh with nit = 2Nh+1 against a large nit: where the curves part, "
                         "the few time samples alias the contact forces.", "Fig. 6"),
    "iterations": ("Solver iterations per frequency: peaks mark where the contact state changes (stick → slip); "
                   "a method that needs many more there is the harder one to converge.", "Fig. 7"),
    "tangential": ("Tangential relative displacement of one contact pair over one period at resonance: flat parts "
                   "are stick, sloped parts slip; the methods should overlay.", "Fig. 8"),
    "error_vs_time": ("FRF error against the converged reference versus the wall time of each variant's sweep "
                      "(filled markers: fixed nit, open: nit = 2Nh+1): the lower-left point is the best buy; below "
                      "the dashed line, the reference's own uncertainty, an error is not resolved.", ""),
    "wear_profile": ("Wear depth W per contact pair at the worn steady state, per method: the profiles should "
                     "coincide; the tallest bars are where the flank wears first.", "Fig. 9"),
    "tip_cycle": ("Tip displacement over one period before wear and at each method's worn steady state: the "
                  "worn curves should overlay (the paper's Fig. 10 compares the methods); their change from the "
                  "unworn curve is what wear does to the blade's response.", "Fig. 10"),
    "max_wear": ("Deepest wear against cycles (physical for the march, pseudo for pseudo-time): the curve "
                 "flattening is the worn steady state.", "Fig. 11"),
    "harmonic1": ("First harmonic of the tracked pair's tangential displacement against cycles: it settles when "
                  "the wear stops redistributing the contact.", "Fig. 12"),
    "wear_flanks": ("Each flank unrolled, coloured by wear depth [µm]: where (leading/trailing edge, top/bottom) "
                    "and how deep each flank wore.", "Fig. 3 (contact grid)"),
    "wear_sector": ("The sector with the blade pulled axially out of the disk, flanks coloured by wear depth: "
                    "the worn zones in place. The interactive view above can be turned.", ""),
    "frf_worn_vs_new": ("Nonlinear FRF of the new and the worn model on one grid: the peak's shift is the worn "
                        "blade's frequency change.", ""),
    "convergence": ("Reduced-model frequency error against the number of fixed-interface modes.", ""),
    "scaling": ("Run time against problem size.", ""),
    "nd_map": ("Frequencies of the tuned disk against nodal diameter, one line per mode family (interface tied): "
               "flat families are blade-dominated (the disk barely couples the blades), rising ones disk-dominated.",
               ""),
    "campbell": ("Frequencies of every nodal diameter against speed with engine-order lines: circles are the "
                 "resonances an EO excites (its lines meet the modes of ND EO mod N, folded).", ""),
    "zzenf": ("ZZENF: the nodal-diameter map with the zig-zag of the engine-order excitation at the scene's speed; "
              "a mode on the zig-zag is resonant.", ""),
}


#: Keys that name one figure exactly (no prefix match: ``frf_nh1_3`` is not ``frf_nh1_35``).
EXACT = ("frf_nh1_3", "frf_nh7_17")


def caption(stem: str) -> tuple[str, str]:
    """(what to look at, paper figure) for a figure file stem; the longest
    matching key wins (``frf_nh3_5`` → ``frf_nh``, ``frf_nh1_3`` → itself)."""
    keys = [k for k in CAPTIONS if stem == k or (k not in EXACT and stem.startswith(k))]
    return CAPTIONS[max(keys, key=len)] if keys else ("", "")


def table1_side_by_side(cpu_rows: list[dict], runs=()) -> list[dict]:
    """Rows ``{"Nh", "column", "ours", "paper", "paper_text", "not_converged"}``
    for every (Nh, method, nit) that both the run's ``cpu_table.csv`` rows and
    the paper's Table 1 have (normalised CPU, dimensionless; ``paper_text`` as
    printed); ``not_converged`` counts the variant's points that gave up (from
    the hb summary's ``runs``: their CPU is in the cell too)."""
    gave_up = {}
    for r in runs:
        nit = "105" if int(r.get("time_samples", 0)) == 105 else (
            "2Nh+1" if int(r.get("time_samples", 0)) == 2 * int(r.get("harmonics", 0)) + 1 else None)
        if nit and r.get("points") is not None and r.get("converged_points") is not None:
            gave_up[(int(r["harmonics"]), r.get("method"), nit)] = int(r["points"]) - int(r["converged_points"])
    ours = {}
    for r in cpu_rows:
        try:
            ours[(int(float(r["Nh"])), r["method"], r["nit_label"])] = float(r["normalised"])
        except (KeyError, ValueError):
            continue
    out = []
    for nh, values in TABLE1.items():
        for (method, nit), paper, text in zip(TABLE1_COLUMNS, values, TABLE1_TEXT[nh]):
            if (nh, method, nit) in ours:
                out.append({"Nh": nh, "column": f"{method.upper()} nit={nit}", "ours": ours[(nh, method, nit)],
                            "paper": paper, "paper_text": text, "not_converged": gave_up.get((nh, method, nit), 0)})
    return out


def cpu_ratio_52(wear: dict) -> dict | None:
    """Our pseudo-time / reference-march time ratio beside the paper's §5.2 29 %.

    The reference is the implicit DLFT march when the scene ran it (the paper's
    "implicit method with DLFT", 100 %), else the explicit one: the wear
    engine's rule (workflow/engine/studies/wearstudy/steady.py). Times [s] are the wear
    study's wall-clock seconds per method; the paper's are CPU shares."""
    r = (wear or {}).get("cpu_ratio_pseudo_over_reference")
    if r is None:
        return None
    methods = wear.get("methods") or {}
    ref = next((m for m in ("implicit", "explicit") if m in methods), None)
    sec = {m: (methods.get(m) or {}).get("seconds") for m in (ref, "pseudo-time") if m}
    return {"ours": float(r), "paper": CPU_RATIO_52, "reference": ref or "reference",
            "reference_seconds": sec.get(ref), "pseudo_seconds": sec.get("pseudo-time"),
            "profile_max_rel_diff": wear.get("profile_max_rel_diff")}
