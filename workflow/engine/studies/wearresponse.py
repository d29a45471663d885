"""The wear response curve (issue 48 item 1): the worn steady state against f / f_r, f_r the
model's friction-damped resonance (:mod:`workflow.engine.studies.operating`), each point one
pseudo-time march (:func:`workflow.engine.studies.wearstudy.worn_steady_state`), and where the
curve peaks.

Wear lowers the resonance. A blade excited just below its new peak wears until the peak has
been dragged through the excitation (its worn detuning f / f_r,worn ends above 1); a little lower
the first vibration is too weak for that, the worn resonance stays above the excitation (worn
detuning below 1) and the blade wears an order of magnitude less. The curve's maximum is the
edge of that cliff, a fold rather than a smooth peak, so a sampled curve reads it only as well as
its samples happen to fall: :func:`cliff` finds the two neighbouring points that straddle it and
:func:`wear_response` halves that bracket by marches of its own (``refine``).
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from workflow.engine.studies.operating import friction_damped_resonance, resonance_shift
from workflow.engine.studies.wearstudy import worn_steady_state


def wear_response(model, law, opt, detunings, keep_states: bool = False, report=None, refine: int = 0) -> dict:
    """The wear response curve: the worn steady state at each ``detunings`` r × the model's
    friction-damped resonance f_r (found once) — what a designer reads instead of one number at
    one frequency. ``opt``: the :class:`~workflow.engine.studies.wearstudy.WearOptions` of each
    march (pseudo-time; the per-point checks off: a curve of marches).
    {"resonance_hz", "rows": [{"detuning", "frequency_hz", "steady", "max_wear_m",
    "worn_volume_m3", "energy_new_J", "persistent_slip", "reason", "seconds", "refined"}], "peak",
    "seconds"}, rows in order of r; a point without a worn steady state (persistent slip: the wear
    feeds the vibration) says so, its depth where the march stopped. With ``opt.resonance_shift``
    each row also gives the worn blade's friction-damped resonance ``worn_resonance_hz`` and the
    detuning it sees, ``worn_detuning`` = f / f_r,worn (None where it is not found).

    ``refine``: with the worn detunings, that many bisections of the cliff (:func:`cliff`), each
    one more march (rows with ``refined`` true). ``peak`` (:func:`peak`) says where the curve's
    largest worn volume is, the cliff's bracket and how much the last bisection moved the peak.
    ``keep_states``: each row also holds its worn depth ``"W"`` (p,) [m] (for measures of the
    profile; not JSON); ``report(message)``: one line a point done."""
    t0 = time.perf_counter()
    res = friction_damped_resonance(model, law, method=opt.method, nh=opt.nh, nit=opt.nit, tol=opt.tol,
                                    max_iterations=opt.max_iterations, max_passes=opt.max_passes)
    rows = [_point(model, law, opt, r, res, keep_states, report) for r in sorted(float(d) for d in detunings)]
    refine = refine if opt.resonance_shift else 0
    rows = bisect_cliff(rows, lambda r: _point(model, law, opt, r, res, keep_states, report, refined=True), refine)
    return {"resonance_hz": res["hz"], "rows": rows, "peak": peak(rows, refine), "seconds": time.perf_counter() - t0}


def bisect_cliff(rows, point, n: int) -> list:
    """``rows`` and up to ``n`` more, each ``point(r)`` (a row, ``refined`` true) at the middle of
    the current :func:`cliff`, sorted by detuning: the bracket halves with each. Fewer where the
    cliff is lost (no crossing) or its middle is a point already marched whose side is unknown
    (:func:`cliff`): marching it again would tell nothing new."""
    rows = sorted(rows, key=lambda row: row["detuning"])
    for _ in range(n):
        bracket = cliff(rows)
        if bracket is None:
            break
        mid = 0.5 * (bracket[0] + bracket[1])
        if any(row["detuning"] == mid for row in rows):
            break
        rows = sorted([*rows, point(mid)], key=lambda row: row["detuning"])
    return rows


def _point(model, law, opt, r: float, res: dict, keep_states: bool, report, refined: bool = False) -> dict:
    """One row of :func:`wear_response`: the worn steady state at r × f_r (``res`` the new
    blade's resonance, :func:`friction_damped_resonance`)."""
    t = time.perf_counter()
    one = replace(opt, methods=("pseudo-time",), operating_point="frequency", frequency_hz=r * res["hz"],
                  eps_check_factor=0.0, nh_check=False, compare_unworn=False, resonance_shift=False)
    st = worn_steady_state(model, law, one)
    h = st.histories["pseudo-time"]
    row = {"detuning": r, "frequency_hz": st.omega / (2 * np.pi), "steady": bool(h.steady),
           "max_wear_m": float(np.max(h.W)), "worn_volume_m3": st.measures.get("worn_volume_m3"),
           "energy_new_J": st.energy_per_cycle_J.get("new"), "persistent_slip": bool(h.persistent_slip),
           "reason": h.reason, "refined": refined}
    if opt.resonance_shift:
        worn = resonance_shift(model, law, h.W, opt, new=res).get("worn_hz")
        row.update({"worn_resonance_hz": worn, "worn_detuning": None if worn is None else row["frequency_hz"] / worn})
    row["seconds"] = time.perf_counter() - t
    if keep_states:
        row["W"] = np.asarray(h.W, float).copy()
    if report is not None:
        report(f"wear response: f/f_r = {r:.6g}: max W {row['max_wear_m']:.4g} m, steady {row['steady']}, "
               f"{row['seconds']:.0f} s")
    return row


def cliff(rows) -> tuple[float, float] | None:
    """(r_lo, r_hi): the neighbouring detunings of ``rows`` (each with ``detuning`` and
    ``worn_detuning``) between which the worn detuning crosses 1 — below r_lo's worn blade kept
    its resonance above the excitation, at r_hi the wear dragged it below. A point whose side is
    unknown (:func:`_side`) is passed over (it may lie inside the bracket, :func:`peak` names it).
    Of several crossings the one whose upper point wore the most; None without a crossing."""
    known = sorted((row for row in rows if _side(row) is not None), key=lambda row: row["detuning"])
    best = None
    for a, b in zip(known, known[1:]):
        if not _side(a) < 1.0 <= _side(b):
            continue
        if best is None or (b.get("worn_volume_m3") or 0.0) > (best[1].get("worn_volume_m3") or 0.0):
            best = (a, b)
    return None if best is None else (best[0]["detuning"], best[1]["detuning"])


def _side(row):
    """A point's worn detuning f / f_r,worn, None where its side of the cliff is unknown: its worn
    resonance not found, or its march stopped short of a worn steady state with the resonance
    still above the excitation (more wear could drag it through). Stopped with the resonance
    already below the excitation, the point is above the cliff whatever it wears on: wear only
    lowers the resonance further."""
    wd = row.get("worn_detuning")
    return wd if wd is not None and (row.get("steady", True) or wd >= 1.0) else None


def peak(rows, bisections: int) -> dict:
    """Where the curve's worn volume is largest, over its worn steady states: {"detuning",
    "worn_volume_m3", "max_wear_m" (None without one), "cliff" ([r_lo, r_hi] or None),
    "no_cliff" (why there is none, else None), "bisections" (asked), "refined" (made),
    "upper_volumes", "change_last", "hidden_rel", "unknown_inside", "not_steady"}.

    ``upper_volumes`` [m³]: the worn volume of the lowest worn steady state above the cliff, each
    time a refined point moved it (the first the sampled one): the sequence that tends to the
    curve's maximum as the bracket shrinks; ``change_last`` its last step relative to its last
    value (None before a refined point has moved it); ``hidden_rel``: how much more the curve may
    wear inside the bracket, relative to that lowest worn steady state — the slope of the two
    lowest above the cliff carried across the bracket (a linear estimate; None with one);
    ``unknown_inside``: the detunings inside the bracket whose side is unknown (:func:`_side`);
    ``not_steady``: every detuning whose march stopped short of a worn steady state (next to the
    cliff, a pair that wears on at a constant pace)."""
    def volume(row):
        return row.get("worn_volume_m3") or 0.0

    # a march stopped short of a worn steady state gives no worn state, however deep
    top = max((row for row in rows if row["steady"]), key=volume, default=None)
    bracket = cliff(rows)
    uppers, hidden, unknown = [], None, []
    if bracket is not None:
        hi = bracket[1]
        unknown = [row["detuning"] for row in rows if bracket[0] < row["detuning"] < hi]
        above = sorted((row for row in rows if row["detuning"] >= hi and row["steady"] and _side(row) is not None),
                       key=lambda row: row["detuning"])
        sampled = [row for row in above if not row.get("refined")]
        moved = sorted((row for row in above if row.get("refined")), key=lambda row: -row["detuning"])
        uppers = [volume(row) for row in sampled[:1] + moved]
        if len(above) > 1 and volume(above[0]) > 0:
            slope = (volume(above[0]) - volume(above[1])) / (above[1]["detuning"] - above[0]["detuning"])
            hidden = max(slope, 0.0) * (hi - bracket[0]) / volume(above[0])
    change = (uppers[-1] - uppers[-2]) / uppers[-1] if len(uppers) > 1 and uppers[-1] > 0 else None
    no_cliff = None
    if bracket is None:
        no_cliff = ("no worn resonances (resonance_shift off)" if all(r.get("worn_detuning") is None for r in rows)
                    else "the worn detuning f / f_r,worn does not cross 1 between the points")
    return {"detuning": None if top is None else top["detuning"],
            "worn_volume_m3": None if top is None else top.get("worn_volume_m3"),
            "max_wear_m": None if top is None else top["max_wear_m"],
            "cliff": None if bracket is None else list(bracket), "no_cliff": no_cliff, "bisections": bisections,
            "refined": sum(bool(row.get("refined")) for row in rows), "upper_volumes": uppers, "change_last": change,
            "hidden_rel": hidden, "unknown_inside": unknown,
            "not_steady": [row["detuning"] for row in rows if not row["steady"]]}
