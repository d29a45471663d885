"""The largest blade peak of a mistuned disk's response, by every blade's own resonance (issue 50).

A mistuned disk's blades peak at their own frequencies, many within one step of a coarse grid
near the tuned resonance. The largest amplitude over the blades then has a peak for each of them,
and a scalar search on it converges to whichever it meets first. Here each blade's resonance is
modelled from its own solved points (:func:`resonance_vertices`), the blades predicted highest are
evaluated in turn until each is resolved (:func:`search_blade_peaks`), and the tied response's
highest blades say where to look first (:func:`tied_candidates`). Frequencies in Hz, amplitudes in m.
"""
from __future__ import annotations

import numpy as np

#: a predicted peak this close (relative) to a solved frequency is resolved (:func:`search_blade_peaks`)
PEAK_XTOL = 1e-5
#: most evaluations of one peak search (:func:`search_blade_peaks`): patterns 1–3 of the quick disk
#: resolve in 15, 25 and 21
PEAK_BUDGET = 32
#: peaks predicted this close (relative) below the best are resolved too (:func:`search_blade_peaks`): a
#: parabola through distant points predicts low; on ten lumped patterns 0.2 % lost one peak (4.7 % higher), 1 % none
PEAK_MARGIN = 0.01
#: a blade's peak is resolved when its solved neighbours lie this close (relative) (:func:`search_blade_peaks`)
PEAK_BRACKET = 1e-4
#: the friction-damped search first evaluates where this many blades peak highest tied (:func:`tied_candidates`)
PEAK_CANDIDATES = 3


def resonance_vertices(freqs_hz, amplitudes, limits=None):
    """Every blade's predicted peaks, one for each local maximum of its solved amplitudes (a
    blade takes part in its neighbours' modes too, so its curve has several; a maximum at an end
    of the band counts, the blade may peak just inside it): near a resonance 1/A² is a parabola
    in f (a single mode, ``|k − mω² + icω|²`` expanded about ω₀), so the parabola through the
    three values of 1/A² at the maximum and its two nearest points has its vertex at the peak.
    ``freqs_hz`` (n,) sorted; ``amplitudes`` (n, N) [m]. Returns (m,) arrays over the m maxima:
    the vertex f* [Hz] (kept inside its bracket: the neighbours, or a limit), its A* [m], the
    maximum's frequency f_k [Hz], the wider side of its bracket [Hz], signed (> 0 above f_k; the
    parabola is as good as that side is small against the peak's width), and the narrower side's
    width [Hz]. A* = inf where the parabola has no positive minimum (the
    model does not hold: f* is then the middle of the wider half, to be evaluated).

    ``limits`` (lo, hi) [Hz] (None: the solved band's ends): how far a maximum at an end of the
    solved points may lie from its peak. Beyond that end the bracket reaches the limit, unexplored:
    the vertex may lie out there, and the wider side is that unexplored span until a point is solved
    at the limit (a mistuned disk's highest blade can peak outside the grid it was first solved on)."""
    f, A = np.asarray(freqs_hz, float), np.asarray(amplitudes, float)
    if f.size < 3:
        return (np.zeros(0),) * 5
    lo_f, hi_f = (f[0], f[-1]) if limits is None else (min(float(limits[0]), f[0]), max(float(limits[1]), f[-1]))
    mid = A[1:-1]
    kk, blade = np.nonzero((mid >= A[:-2]) & (mid >= A[2:]) & (mid > 0))
    lo, hi = np.flatnonzero((A[0] >= A[1]) & (A[0] > 0)), np.flatnonzero((A[-1] >= A[-2]) & (A[-1] > 0))
    n = f.size
    k = np.concatenate([kk + 1, np.zeros(lo.size, int), np.full(hi.size, n - 1)])
    blade = np.concatenate([blade, lo, hi])
    i0 = np.clip(k - 1, 0, n - 3)                          # the three points: k and its nearest two
    x = f[np.stack([i0, i0 + 1, i0 + 2])]
    with np.errstate(divide="ignore", invalid="ignore"):
        y = 1.0 / A[np.stack([i0, i0 + 1, i0 + 2]), blade] ** 2
        d1, d2 = (y[1] - y[0]) / (x[1] - x[0]), (y[2] - y[1]) / (x[2] - x[1])
        c = (d2 - d1) / (x[2] - x[0])
        fs = 0.5 * (x[0] + x[1]) - 0.5 * d1 / c
        f_lo = np.where(k > 0, f[np.maximum(k - 1, 0)], lo_f)                 # the bracket, to the limits
        f_hi = np.where(k < n - 1, f[np.minimum(k + 1, n - 1)], hi_f)
        fs = np.clip(fs, f_lo, f_hi)
        qs = y[0] + d1 * (fs - x[0]) + c * (fs - x[0]) * (fs - x[1])
        model = (c > 0) & (qs > 0) & np.isfinite(fs)
        As = np.where(model, 1.0 / np.sqrt(np.where(model, qs, 1.0)), np.inf)
    below, above = f[k] - f_lo, f_hi - f[k]
    wide = np.where(above >= below, above, -below)
    return np.where(model, fs, f[k] + 0.5 * wide), As, f[k], wide, np.minimum(below, above)


def search_blade_peaks(evaluate, solved: dict, *, xtol: float = PEAK_XTOL,
                       bracket: float = PEAK_BRACKET, margin: float = PEAK_MARGIN, budget: int = PEAK_BUDGET,
                       candidates=(), limits=None) -> dict:
    """Refine the largest blade peak among ``solved`` ({f [Hz]: (N,) blade amplitudes [m]}, the
    grid) in place, by every blade's own resonance (:func:`resonance_vertices`).

    Why every blade: near the tuned resonance many blades peak within one grid step, and the blade
    largest at a grid point is not the one that peaks highest (on the quick disk the sixth at the
    grid's best point did, 1.6 % above the first's peak); a search on the largest amplitude over
    the blades converges to any of their peaks. ``candidates`` [Hz] are evaluated first (the tied
    response's highest blade peaks, :func:`tied_candidates`). Then, one evaluation at a time, the
    predicted peak highest among those still open is evaluated at its vertex, or, where its vertex
    already lies within ``xtol`` (relative) of a solved point, into its bracket's wider side as far
    as its narrower side reaches (a quarter of the wider at most; the parabola's vertex through
    distant points can sit beside the peak: 7e-4 low on a lumped disk). That probe brackets the
    peak or finds a higher point: on the quick disk the quarter steps it replaces took 4–6 solves
    to close a 6 Hz side. A peak's bracket is tight when its solved neighbours lie within ``bracket``
    (relative) on both sides; its parabola is then trusted, and it is open while its vertex is not
    yet solved and lies above the best solved amplitude. With a wider bracket it is open while its
    prediction is within ``margin`` of the best (or above). Stops when none is open, or after
    ``budget`` evaluations. ``limits`` (lo, hi) [Hz]: how far beyond the solved points a peak may be
    sought (:func:`resonance_vertices`; None: within them). ``evaluate(f)`` → (N,) amplitudes [m]
    or None (unconverged: not tried again). The peak is the largest over every solved point, never
    below the grid's. Returns {"evaluations", "predicted_gain": how far the highest prediction left
    open lies above the peak found (relative, ≥ 0; inf where its parabola has no positive minimum),
    "resolved": none left open}."""
    n, failed = 0, []

    def run(g):
        nonlocal n
        n += 1
        a = evaluate(g)
        if a is None:
            failed.append(g)
        else:
            solved[g] = np.asarray(a, float)

    for g in map(float, candidates):
        if n < budget and min(abs(h - g) for h in list(solved) + failed) > xtol * g:
            run(g)
    def dist(x, pts):
        return np.min(np.abs(x[:, None] - np.asarray(pts, float)[None]), axis=1)

    gain, open_ = 0.0, np.zeros(0, bool)
    while True:
        f = np.array(sorted(solved))
        if f.size < 3:
            break
        A = np.array([solved[g] for g in f])
        fs, As, fk, wide, narrow = resonance_vertices(f, A, limits)
        h = np.abs(wide)
        valid = np.isfinite(fs)
        at_solved = valid & (dist(fs, f) <= xtol * fs)
        tight = h <= bracket * fk
        best = float(A.max())
        # a tight bracket's parabola is trusted; a wide one's only beyond ``margin`` below the best
        settled = tight & (at_solved | (As <= best))
        open_ = valid & ~settled & (As >= best * np.where(tight, 1.0, 1.0 - margin))
        gain = max(float(np.max(As[open_]) / best - 1.0), 0.0) if open_.any() else 0.0
        # a vertex on a solved point with one side still wide: probe that side as close as the
        # narrow one (the peak is then bracketed, or a higher point found), a quarter of it at most
        step = np.minimum(0.25 * h, np.maximum(narrow, bracket * fk))
        point = np.where(at_solved, fk + np.sign(wide) * step, fs)
        todo = open_ & (dist(point, list(f) + failed) > xtol * point)
        if not todo.any() or n >= budget:
            break
        run(float(point[todo][np.argmax(As[todo])]))
    return {"evaluations": n, "predicted_gain": gain, "resolved": not open_.any()}


def peak_of(solved: dict, search: dict | None, limits=None) -> dict:
    """{"hz", "amplitude_m", "blade"} of the largest blade amplitude over ``solved`` ({f [Hz]: (N,)
    amplitudes [m]}), with the search's ``predicted_gain``, ``resolved`` and its evaluations as
    ``search_points`` (:func:`search_blade_peaks`; None, None, 0 without a search), and
    ``at_band_edge``: the peak lies at one of ``limits`` (lo, hi) [Hz] (within ``PEAK_XTOL``), where
    the blade may still rise beyond — then it is not ``resolved``, whatever the search said."""
    f_pk = max(solved, key=lambda g: np.max(solved[g]))
    a_pk = solved[f_pk]
    search = search or {}
    edge = limits is not None and min(abs(f_pk - float(g)) for g in limits) <= PEAK_XTOL * f_pk
    resolved = search.get("resolved")
    return {"hz": f_pk, "amplitude_m": float(np.max(a_pk)), "blade": int(np.argmax(a_pk)),
            "predicted_gain": search.get("predicted_gain"), "resolved": False if edge else resolved,
            "at_band_edge": bool(edge), "search_points": search.get("evaluations", 0)}


def tied_candidates(freqs_hz, tied, k: int = PEAK_CANDIDATES) -> list:
    """The ``k`` frequencies [Hz] where blades are predicted to peak highest in the tied response
    (:func:`resonance_vertices` of ``tied`` (n, N) [m] on ``freqs_hz``), highest first: where the
    friction-damped search looks first. Why: friction damps the blades' localised peaks without
    moving them much, and keeps their order (the quick disk's pattern 1, a 51-point friction scan
    against a 201-point tied one: the seven highest blades in the same order, each friction peak
    within one scan step, 0.06 Hz, of its tied peak), while the friction grid's few points fall
    between them."""
    fs, As = resonance_vertices(freqs_hz, tied)[:2]
    out = []
    for i in np.argsort(np.where(np.isfinite(As), As, -np.inf))[::-1]:
        if len(out) == int(k) or not np.isfinite(As[i]):
            break
        if all(abs(fs[i] - g) > PEAK_BRACKET * g for g in out):     # a mode several blades share, once
            out.append(float(fs[i]))
    return out
