"""One reduced model of a contact-mesh study (issue 17) and the study's convergence arithmetic.

Per mesh: the friction-damped FRF peak and its dissipated energy
(:func:`friction_peak`), the static preload gaps at the midside nodes
(:func:`static_gaps`), the pseudo-time worn profile (:func:`worn_profile`);
over the meshes: relative changes and observed orders (:func:`summarise`).
Arrays and result dicts in and out; the contact-convergence stage reads the
scene and writes the files.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from workflow.engine.errors import SolverError

#: Gap added to switched-off pairs [m]: far beyond any vibration, so they never close.
OPEN_GAP = 1.0


def area_penalty(law, area: np.ndarray, per_area: float):
    """``law`` with ε_N,i = ε_T,i = ``per_area`` · A_i [N/m] when ``per_area``
    [N/m³] is > 0: an interface stiffness per unit area that does not change
    with the mesh (the automatic ε is a per-pair stiffness, so it does).
    Unchanged otherwise."""
    k = float(per_area)
    if k <= 0:
        return law
    eps = k * np.asarray(area, dtype=float)
    return law.with_penalty(eps, eps.copy())


def mesh_law(model, *, mu, eps_n: float, eps_t: float, gap: float, factor: float, per_area: float = 0.0,
             rc=None):
    """The DLFT law on ``model`` (the engine's penalty decision,
    :func:`workflow.engine.contact_law`, or :func:`area_penalty` when
    ``per_area`` > 0) and its ε-path (:func:`workflow.engine.penalty.path_of`; none for
    the per-area penalty, a user's value)."""
    from workflow.engine import penalty
    from workflow.engine.studies.study import contact_law

    from workflow.engine.condense import relative_coordinates
    from workflow.engine.linear import condensed

    rc = relative_coordinates(model) if rc is None else rc
    law = contact_law(model, mu=model.friction(mu)[0], eps_n=eps_n, eps_t=eps_t, gap=gap, factor=factor, rc=rc)
    if per_area > 0:
        return area_penalty(law, model.area, per_area), ()
    return law, penalty.path_of(law, np.real(condensed(rc, 0.0, 0).Zr[0]))


def friction_peak(model, law, eps_path, variant, *, band: float, points: int, xtol: float, solver_kw: dict,
                  rc=None) -> dict:
    """Friction-damped peak of ``model``: ``peak_hz``, ``peak_amplitude_m`` (first
    harmonic at the observed DOFs), ``energy_J`` (friction, per cycle, at the
    peak, :func:`workflow.engine.dissipation.energy_per_cycle` on the DLFT slip path),
    ``grid_hz``/``grid_m`` (the coarse sweep; ``grid_converged`` of its points
    converged), ``evaluations``, ``tied_hz``,
    the mean penalties and whether the coarse maximum sat at the band's edge.

    A coarse grid of ``points`` frequencies over ± ``band`` (fraction) of the
    first excited tied frequency brackets the maximum, a bounded scalar
    search (:func:`scipy.optimize.minimize_scalar`, ``xtol`` × f_tied) refines
    it; ``variant`` (HBM, Nh, nit) with ``law`` and its ``eps_path`` and the
    engine's static state at every frequency. ``solver_kw``: ``solver``,
    ``tol``, ``maxiter``, ``max_passes`` of :func:`workflow.engine.studies.frf.sweep_variant`.
    """
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.studies.peak import refine_peak
    from workflow.engine.studies.frf import sweep_variant
    from workflow.engine.linear import CondensedGrid, first_excited_mode
    from workflow.engine.studies.study import static_state

    rc = relative_coordinates(model) if rc is None else rc
    f_tied, _ = first_excited_mode(rc)
    grid = np.linspace((1 - band) * f_tied, (1 + band) * f_tied, int(points))
    cond = CondensedGrid(rc, 2 * np.pi * grid, variant.nh)
    static = static_state(cond[0].Zr, cond[0].Fr, law, solver_kw["max_passes"])
    kw = dict(solver_kw, eps_path=eps_path)
    sw = sweep_variant(rc, cond, law, static, variant, **kw)
    if not sw.converged.any():
        raise SolverError(f"contact_convergence: no frequency of the peak bracket converged ({sw.reasons[0]})")
    pk = refine_peak(rc, sw, law, static, variant, xtol * f_tied, **kw)
    f_pk, a_pk, U_pk, c_pk, i = pk.hz, pk.amplitude, pk.Ur, pk.cond, pk.grid_index
    energy = _energy(model, law, variant, c_pk, U_pk, static, solver_kw["max_passes"])
    return {"peak_hz": float(f_pk), "peak_amplitude_m": float(a_pk), "energy_J": energy,
            "grid_hz": grid, "grid_m": sw.amplitude, "grid_converged": int(sw.converged.sum()),
            "evaluations": pk.evaluations, "tied_hz": float(f_tied),
            "eps_n": float(np.mean(law.eps_n)), "eps_t": float(np.mean(law.eps_t)),
            "at_band_edge": bool(i in (0, len(grid) - 1))}


def _energy(model, law, variant, c, U, static, max_passes: int) -> float:
    """Friction energy per cycle [J] at the harmonics ``U`` of the condensed point ``c``."""
    from workflow.engine.dissipation import energy_per_cycle
    from workflow.engine.hb import HBProblem
    from workflow.engine.wear import WearProblem

    prob = HBProblem(c.Zr, c.Fr, law, variant.nh, variant.nit, "hbm", max_passes=max_passes, static=static)
    st = WearProblem(prob, model.area, 0.0).evaluate(prob.unknowns_from_harmonics(U))
    return float(energy_per_cycle(st.lam[..., 1:], st.slip).sum())


def flank_bearing(model, st, gap) -> list[dict]:
    """How each flank bears under the preload (a :class:`~workflow.engine.hb.StaticState` ``st``,
    initial gaps ``gap`` (p,) [m]): ``open_share`` of its area, ``max_lift_off_m`` (the largest
    normal gap u_N + gap), ``max_pressure_pa`` and ``normal_load_n``. On the contact-convergence
    sector both flanks bear on one long edge (docs/contact-layout.md): the edge row's pressure
    grows as 1/h across the flank, a line load the contact mesh does not resolve."""
    A, fl = np.asarray(model.area, float), np.asarray(model.flank)
    out = []
    for f in np.unique(fl):
        i = np.flatnonzero(fl == f)
        p = -st.lam[i, 0] / A[i]
        out.append({"flank": int(f), "open_share": float(A[i][p <= 0].sum() / A[i].sum()),
                    "max_lift_off_m": float(max(np.max(st.u[i, 0] + gap[i]), 0.0)),
                    "max_pressure_pa": float(p.max()), "normal_load_n": float(-st.lam[i, 0].sum())})
    return out


def static_gaps(model, law, vertex: np.ndarray, max_passes: int, rc=None) -> dict:
    """Static preload state of ``model``: normal gap ``u_N + gap`` [m] at the
    midside pairs (``~vertex``) — negative is interpenetration — with every
    pair active and with only the vertex pairs active (midside pairs opened
    by :data:`OPEN_GAP`); the vertex pairs' share of the normal load; pairs
    in contact. A model with tied midside nodes (``info["tie_pairs"]``, the
    ``"linear"`` layout) has no midside pairs: its midside gaps are the mean
    of the gaps at the edge's two ends (the two flank surfaces are linear
    between the vertices; exact on the planar dovetail flanks)."""
    from workflow.engine.condense import relative_coordinates
    from workflow.engine.linear import condensed
    from workflow.engine.studies.study import static_state

    rc = relative_coordinates(model) if rc is None else rc
    c = condensed(rc, 0.0, 0)
    gap = np.asarray(law.gap, dtype=float)
    out = {"pairs_in_contact": None, "midside_gap_min_m": None, "vertex_only_midside_gap_min_m": None,
           "vertex_load_share": None}
    st = static_state(c.Zr, c.Fr, law, max_passes)
    out["pairs_in_contact"] = int(np.count_nonzero(st.state))
    out["flanks"] = flank_bearing(model, st, gap)
    lam_n = np.maximum(-st.lam[:, 0], 0.0)
    out["vertex_load_share"] = float(lam_n[vertex].sum() / max(lam_n.sum(), 1e-300))
    ties = np.asarray(model.info.get("tie_pairs") or np.zeros((0, 2)), dtype=np.int64).reshape(-1, 2)
    if ties.size:
        g = st.u[:, 0] + gap
        out["midside_gap_min_m"] = float((0.5 * (g[ties[:, 0]] + g[ties[:, 1]])).min())
    mids = ~np.asarray(vertex, bool)
    if mids.any():
        out["midside_gap_min_m"] = float((st.u[mids, 0] + gap[mids]).min())
        off = replace(law, gap=gap + np.where(mids, OPEN_GAP, 0.0))
        st2 = static_state(c.Zr, c.Fr, off, max_passes)
        out["vertex_only_midside_gap_min_m"] = float((st2.u[mids, 0] + gap[mids]).min())
    return out


def worn_profile(model, law, eps_path, options, report=None) -> dict:
    """Worn steady state of ``model`` by pseudo-time wear (eq. 22,
    :func:`workflow.engine.worn_steady_state` with ``options``, a
    :class:`~workflow.engine.WearOptions` whose methods include
    ``"pseudo-time"``): ``W`` (p,) [m], ``steady``, ``steps``, ``frequency_hz``, and the wear
    measures, energies, operating point and resonance shift of :class:`WearStudy`, and
    ``reason``, why the march stopped; ``cycles`` (k,) and ``W_history`` (k, p) [m] the march's
    path (pseudo-time in cycles: the physical wear path to ``pseudotime.wear_rtol``). ``report``:
    the march's progress messages (:func:`~workflow.engine.studies.wearstudy.worn_steady_state`)."""
    from workflow.engine.studies.wearstudy import worn_steady_state

    study = worn_steady_state(model, law, options, eps_path=eps_path, report=report)
    h = study.histories["pseudo-time"]
    return {"W": np.asarray(h.W, dtype=float), "steady": bool(h.steady), "steps": int(h.iterations),
            "reason": h.reason, "frequency_hz": float(study.omega / 2 / np.pi), "measures": study.measures,
            "energy_per_cycle_J": study.energy_per_cycle_J, "operating_point": study.operating_point,
            "resonance_shift": study.resonance_shift, "cycles": np.asarray(h.cycles, dtype=float),
            "W_history": np.asarray(h.W_history, dtype=float)}


# ------------------------------------------------------------------ convergence over the meshes

def observed_order(h, q) -> float | None:
    """Order p of ``q(h) = q* + C h^p`` from the last three meshes (sizes ``h``,
    any ratios): solves ``(h₁^p − h₂^p)/(h₂^p − h₃^p) = (q₁ − q₂)/(q₂ − q₃)``.
    None when the changes are not monotone (no asymptotic range yet)."""
    from scipy.optimize import brentq

    if len(q) < 3 or q[-1] is None or q[-2] is None or q[-3] is None:
        return None
    (h1, h2, h3), (q1, q2, q3) = h[-3:], q[-3:]
    if q2 == q3 or (q1 - q2) / (q2 - q3) <= 0:
        return None
    r = (q1 - q2) / (q2 - q3)
    g = lambda p: (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - r  # noqa: E731
    lo, hi = 0.05, 12.0
    if g(lo) * g(hi) > 0:
        return None
    return float(brentq(g, lo, hi))


def grid_convergence_index(h, q, safety: float = 1.25) -> float | None:
    """Roache's grid-convergence index of the finest mesh, relative: ``F_s |q₂ − q₃| / (|q₃|
    (r^p − 1))`` with r = h₂/h₃ and p the :func:`observed_order` of the last three meshes
    (F_s = 1.25, three meshes). A band the converged value lies in, |q∞ − q₃| ≤ GCI·|q₃|, once
    the meshes are in the asymptotic range; None without an observed order (changes not
    monotone) or with p < 0.5, where the extrapolation it rests on is not credible."""
    p = observed_order(h, q)
    if p is None or p < 0.5 or q[-1] == 0:
        return None
    r = h[-2] / h[-1]
    return float(safety * abs(q[-2] - q[-1]) / (abs(q[-1]) * (r ** p - 1.0)))


def spread(values) -> dict | None:
    """Median, least, largest and range over the median of a measure over the meshes: its
    sensitivity to the contact mesh where the meshes do not converge (None: fewer than two)."""
    v = np.asarray([x for x in values if x is not None], float)
    if v.size < 2:
        return None
    med = float(np.median(v))
    return {"median": med, "min": float(v.min()), "max": float(v.max()), "meshes": int(v.size),
            "range_rel": float((v.max() - v.min()) / abs(med)) if med else None}


def rel_change(a, b) -> float | None:
    """|b − a| / |b| (None if either is missing)."""
    if a is None or b is None or b == 0:
        return None
    return float(abs(b - a) / abs(b))


def _shift_change(worn: list[dict]) -> float | None:
    """|Δ(worn − new resonance shift)| between the two finest worn meshes, relative to the new
    resonance frequency (the issue's "< 1e-4 relative")."""
    if len(worn) < 2 or any(r.get("resonance_shift_hz") is None for r in worn[-2:]):
        return None
    return abs(worn[-1]["resonance_shift_hz"] - worn[-2]["resonance_shift_hz"]) / worn[-1]["peak_hz"]


def _flank_changes(last2: list[dict]) -> dict | None:
    """{flank: relative change of its worn volume} between two meshes' rows (their
    ``worn_volume_<flank>_m3``), and ``"largest"``: the larger of them — the measure to judge,
    since the total can hold while the flanks trade wear (None without per-flank volumes)."""
    from workflow.engine.wear.measures import FLANK_NAMES

    out = {n: rel_change(last2[0].get(f"worn_volume_{n}_m3"), last2[1].get(f"worn_volume_{n}_m3"))
           for n in FLANK_NAMES.values()}
    known = [v for v in out.values() if v is not None]
    return {**out, "largest": max(known)} if known else None


def summarise(rows: list[dict], profiles: np.ndarray | None) -> dict:
    """Relative changes between the two finest meshes and observed orders; for the
    wear, between the two finest meshes that have a worn profile (``profiles``:
    one per such mesh, coarse to fine)."""
    worn = [r for r in rows if r.get("max_wear_m") is not None]
    last = (lambda k: rel_change(worn[-2].get(k), worn[-1].get(k))) if len(worn) >= 2 else (lambda k: None)
    out = {"peak_change_last": rel_change(rows[-2]["peak_amplitude_m"], rows[-1]["peak_amplitude_m"]),
           "peak_hz_change_last": rel_change(rows[-2]["peak_hz"], rows[-1]["peak_hz"]),
           "energy_change_last": rel_change(rows[-2]["energy_J"], rows[-1]["energy_J"]),
           "max_wear_change_last": last("max_wear_m"), "wear_volume_change_last": last("wear_volume_m3"),
           "changes_last": {"worn_volume": last("wear_volume_m3"), "max_wear": last("max_wear_m"),
                            "profile_l2": last("profile_l2_m"), "filtered_max": last("filtered_max_wear_m"),
                            "resonance_shift": _shift_change(worn),
                            "worn_volume_flanks": _flank_changes(worn[-2:]) if len(worn) >= 2 else None},
           "wear_pairs_last": [r.get("pairs") for r in worn[-2:]] if len(worn) >= 2 else None,
           "observed_order": {k: observed_order([r["h_contact_m"] for r in rs], [r.get(k) for r in rs])
                              for rs, ks in ((rows, ("peak_hz", "peak_amplitude_m", "energy_J")),
                                             (worn, ("max_wear_m", "wear_volume_m3", "profile_l2_m",
                                                     "filtered_max_wear_m"))) for k in ks}}
    out["gci"] = {k: grid_convergence_index([r["h_contact_m"] for r in rs], [r.get(k) for r in rs])
                  for rs, ks in ((rows, ("peak_amplitude_m", "energy_J")),
                                 (worn, ("max_wear_m", "wear_volume_m3", "profile_l2_m"))) for k in ks
                  if len(rs) >= 3 and all(r.get(k) is not None for r in rs[-3:])}
    # the node-wise max depth is a sensitivity, not a converging measure; the unworn friction energy at
    # the wear's operating point drives the worn volume's first rate, so its spread is the volume's floor
    # (docs/contact-layout.md, "What the worn volume's scatter follows")
    out["spread"] = {k: spread([r.get(k) for r in worn]) for k in ("max_wear_m", "wear_volume_m3", "energy_new_J")}
    for k in ("midside_gap_min_m", "vertex_only_midside_gap_min_m"):
        vals = [r[k] for r in rows if r.get(k) is not None]
        out[f"worst_{k}"] = min(vals) if vals else None  # < 0: the flank meshes interpenetrate
    if profiles is not None and len(profiles) >= 2:
        top = max(float(np.abs(profiles[-1]).max()), 1e-300)
        out["profile_change_last"] = float(np.abs(profiles[-1] - profiles[-2]).max() / top)
        out["profile_changes"] = [float(np.abs(profiles[i + 1] - profiles[i]).max() / top)
                                  for i in range(len(profiles) - 1)]
    return out
