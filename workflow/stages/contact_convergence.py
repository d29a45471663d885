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
  (:func:`workflow.dissipation.energy_per_cycle`, on the DLFT slip path);
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

Every call into the harmonic-balance and wear code sits in the three
functions of the first section (:func:`_friction_peak`, :func:`_static_gaps`,
:func:`_worn_profile`), so the engine refactor repoints them in one place.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from workflow.errors import SolverError

NAME = "contact_convergence"
SECTIONS = ("geometry", "material", "rotation", "damping", "excitation", "reduction", "contact", "hb", "wear",
            "pseudotime", "contact_convergence")
NEEDS = ()
PRODUCES = ("contact_convergence",)

CSV, PROFILES = "convergence.csv", "profiles.npz"
#: Gap added to switched-off pairs [m]: far beyond any vibration, so they never close.
OPEN_GAP = 1.0


# ------------------------------------------------------------------ engine calls

def _area_penalty(law, model, cc):
    """``law`` with ε_N,i = ε_T,i = ``cc.penalty_per_area`` · A_i [N/m] when that is > 0:
    an interface stiffness per unit area that does not change with the mesh
    (the automatic ε is a per-pair stiffness, so it does). Unchanged otherwise."""
    k = float(cc.penalty_per_area)
    if k <= 0:
        return law
    eps = k * np.asarray(model.area, dtype=float)
    return law.with_penalty(eps, eps.copy())


def _friction_peak(model, contact, hb, cc) -> dict:
    """Friction-damped peak of ``model``: ``peak_hz``, ``peak_amplitude_m`` (first
    harmonic at the observed DOFs), ``energy_J`` (friction, per cycle, at the
    peak), ``grid_hz``/``grid_m`` (the coarse sweep), ``evaluations``, ``tied_hz``.

    HBM with Nh = ``cc.harmonics``, nit = ``cc.time_samples``; the engine's
    penalty (:func:`_law`) and static state for every frequency.
    """
    from scipy.optimize import minimize_scalar

    from reduction.condense import condense, relative_coordinates
    from workflow.dissipation import energy_per_cycle
    from workflow.engine import Variant, static_state
    from workflow.engine.frf import sweep_variant
    from workflow.engine.linear import first_excited_mode
    from workflow.hb import HBProblem
    from workflow.wear import WearProblem

    rc = relative_coordinates(model)
    f_tied, _ = first_excited_mode(rc)
    v = Variant("hbm", int(cc.harmonics), int(cc.time_samples))
    grid = np.linspace((1 - cc.band) * f_tied, (1 + cc.band) * f_tied, int(cc.points))
    cond = [condense(rc, 2 * np.pi * f, v.nh) for f in grid]
    law, path = _law(model, contact, cc, rc)
    static = static_state(cond[0].Zr, cond[0].Fr, law, contact.max_passes)
    kw = dict(solver=hb.solver, tol=hb.tol, maxiter=hb.max_iterations, max_passes=contact.max_passes, eps_path=path)
    sw = sweep_variant(rc, cond, law, static, v, **kw)
    if not sw.converged.any():
        raise SolverError(f"contact_convergence: no frequency of the peak bracket converged ({sw.reasons[0]})")
    solved = {float(f): (a, U, c) for f, a, U, c, ok in zip(grid, sw.amplitude, sw.Ur, cond, sw.converged) if ok}

    def minus_amplitude(f):
        c = condense(rc, 2 * np.pi * f, v.nh)
        seed = solved[min(solved, key=lambda g: abs(g - f))][1]
        r = sweep_variant(rc, [c], law, static, v, seeds=[seed], **kw)
        if not r.converged[0]:
            return 0.0  # an unconverged point cannot be the peak
        solved[float(f)] = (float(r.amplitude[0]), r.Ur[0], c)
        return -float(r.amplitude[0])

    i = int(np.argmax(np.where(sw.converged, sw.amplitude, -np.inf)))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    minimize_scalar(minus_amplitude, bounds=(lo, hi), method="bounded",
                    options={"xatol": cc.peak_xtol * f_tied})
    f_pk = max(solved, key=lambda g: solved[g][0])
    a_pk, U_pk, c_pk = solved[f_pk]
    prob = HBProblem(c_pk.Zr, c_pk.Fr, law, v.nh, v.nit, "hbm", max_passes=contact.max_passes, static=static)
    st = WearProblem(prob, model.area, 0.0).evaluate(prob.unknowns_from_harmonics(U_pk))
    energy = float(energy_per_cycle(st.lam[..., 1:], st.slip).sum())
    return {"peak_hz": float(f_pk), "peak_amplitude_m": float(a_pk), "energy_J": energy,
            "grid_hz": grid, "grid_m": sw.amplitude, "evaluations": len(solved), "tied_hz": float(f_tied),
            "eps_n": float(np.mean(law.eps_n)), "eps_t": float(np.mean(law.eps_t)),
            "at_band_edge": bool(i in (0, len(grid) - 1))}


def _static_gaps(model, contact, vertex: np.ndarray) -> dict:
    """Static preload state of ``model``: normal gap ``u_N + gap`` [m] at the
    midside pairs (``~vertex``) — negative is interpenetration — with every
    pair active and with only the vertex pairs active (midside pairs opened
    by :data:`OPEN_GAP`); the vertex pairs' share of the normal load; pairs
    in contact."""
    from reduction.condense import condense, relative_coordinates
    from workflow.engine import static_state

    rc = relative_coordinates(model)
    c = condense(rc, 0.0, 0)
    law, _ = _law(model, contact, None, rc)
    gap = np.asarray(law.gap, dtype=float)
    out = {"pairs_in_contact": None, "midside_gap_min_m": None, "vertex_only_midside_gap_min_m": None,
           "vertex_load_share": None}
    st = static_state(c.Zr, c.Fr, law, contact.max_passes)
    out["pairs_in_contact"] = int(np.count_nonzero(st.state))
    lam_n = np.maximum(-st.lam[:, 0], 0.0)
    out["vertex_load_share"] = float(lam_n[vertex].sum() / max(lam_n.sum(), 1e-300))
    mids = ~np.asarray(vertex, bool)
    if mids.any():
        out["midside_gap_min_m"] = float((st.u[mids, 0] + gap[mids]).min())
        off = replace(law, gap=gap + np.where(mids, OPEN_GAP, 0.0))
        st2 = static_state(c.Zr, c.Fr, off, contact.max_passes)
        out["vertex_only_midside_gap_min_m"] = float((st2.u[mids, 0] + gap[mids]).min())
    return out


def _worn_profile(model, scene, cc) -> dict:
    """Worn steady state of ``model`` by pseudo-time wear (eq. 22,
    :func:`workflow.engine.worn_steady_state`): ``W`` (p,) [m], ``steady``,
    ``steps``, ``frequency_hz``; the scene's contact, wear and pseudotime
    sections, HBM with the stage's Nh and nit."""
    from reduction.condense import relative_coordinates
    from workflow.engine import worn_steady_state
    from workflow.stages.wear import options

    sc = {"wear": scene["wear"], "contact": scene["contact"], "pseudotime": scene["pseudotime"],
          "hb": replace(scene["hb"], methods=["hbm"], harmonics=[int(cc.harmonics)],
                        time_samples=[int(cc.time_samples)])}
    opt = replace(options(sc), methods=("pseudo-time",), eps_check_factor=0.0, compare_unworn=False)
    law, path = _law(model, scene["contact"], cc, relative_coordinates(model))
    study = worn_steady_state(model, law, opt, eps_path=path)
    h = study.histories["pseudo-time"]
    return {"W": np.asarray(h.W, dtype=float), "steady": bool(h.steady), "steps": int(h.iterations),
            "frequency_hz": float(study.omega / 2 / np.pi)}


def _law(model, contact, cc, rc):
    """The scene's DLFT law on ``model`` (the engine's penalty decision, or
    :func:`_area_penalty` when ``cc.penalty_per_area`` > 0) and its ε-path."""
    from workflow.engine import contact_law, penalty

    law = contact_law(model, mu=model.friction(contact.mu)[0], eps_n=contact.eps_n, eps_t=contact.eps_t,
                      gap=contact.gap, factor=contact.penalty_factor, rc=rc)
    given = contact.eps_n > 0 and contact.eps_t > 0
    if cc is not None and cc.penalty_per_area > 0:
        law, given = _area_penalty(law, model, cc), True
    return law, penalty.path(contact.penalty_factor, user_given=given)


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


def common_points(position: np.ndarray, flank: np.ndarray, shape) -> tuple[np.ndarray, np.ndarray]:
    """A ``shape`` = (along, across) grid of points [m] on each flank, spanning
    the pairs' extent in the flank plane; returns (points (k, 3), flank (k,))."""
    from geometry.flankmap import flank_axes, flank_params

    pts, fl = [], []
    for f in np.unique(flank):
        x = position[flank == f]
        c, axes = flank_axes(x)
        uv = flank_params(x, c, axes)
        u = np.linspace(uv[:, 0].min(), uv[:, 0].max(), int(shape[0]))
        w = np.linspace(uv[:, 1].min(), uv[:, 1].max(), int(shape[1]))
        U, V = np.meshgrid(u, w, indexing="ij")
        pts.append(c + U.reshape(-1, 1) * axes[0] + V.reshape(-1, 1) * axes[1])
        fl.append(np.full(U.size, f))
    return np.concatenate(pts), np.concatenate(fl)


def profile_at(points, pflank, position, flank, W) -> np.ndarray:
    """Wear depth W (p,) [m] of the pairs, interpolated to the common points
    (linear in the flank plane, :func:`geometry.flankmap.interpolate_on_flank`)."""
    from geometry.flankmap import interpolate_on_flank

    out = np.zeros(len(points))
    for f in np.unique(pflank):
        sel = flank == f
        out[pflank == f] = interpolate_on_flank(position[sel], W[sel], points[pflank == f])
    return out


# ------------------------------------------------------------------ convergence

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


def rel_change(a, b) -> float | None:
    """|b − a| / |b| (None if either is missing)."""
    if a is None or b is None or b == 0:
        return None
    return float(abs(b - a) / abs(b))


def summarise(rows: list[dict], profiles: np.ndarray | None) -> dict:
    """Relative changes between the two finest meshes and observed orders."""
    h = [r["h_contact_m"] for r in rows]
    out = {"peak_change_last": rel_change(rows[-2]["peak_amplitude_m"], rows[-1]["peak_amplitude_m"]),
           "peak_hz_change_last": rel_change(rows[-2]["peak_hz"], rows[-1]["peak_hz"]),
           "energy_change_last": rel_change(rows[-2]["energy_J"], rows[-1]["energy_J"]),
           "max_wear_change_last": rel_change(rows[-2]["max_wear_m"], rows[-1]["max_wear_m"]),
           "observed_order": {k: observed_order(h, [r[k] for r in rows])
                              for k in ("peak_hz", "peak_amplitude_m", "energy_J", "max_wear_m")}}
    for k in ("midside_gap_min_m", "vertex_only_midside_gap_min_m"):
        vals = [r[k] for r in rows if r.get(k) is not None]
        out[f"worst_{k}"] = min(vals) if vals else None  # < 0: the flank meshes interpenetrate
    if profiles is not None and len(profiles) >= 2:
        top = max(float(np.abs(profiles[-1]).max()), 1e-300)
        out["profile_change_last"] = float(np.abs(profiles[-1] - profiles[-2]).max() / top)
        out["profile_changes"] = [float(np.abs(profiles[i + 1] - profiles[i]).max() / top)
                                  for i in range(len(profiles) - 1)]
    return out


# ------------------------------------------------------------------ the stage

def run_level(scene, na: int, nc: int, work: Path, log) -> tuple[dict, dict]:
    """One contact mesh: its table row and its raw results (model, W)."""
    cc = scene["contact_convergence"]
    t0 = time.perf_counter()
    model, vertex, info = build_model(scene, na, nc, work)
    t_build = time.perf_counter() - t0
    t1 = time.perf_counter()
    pk = _friction_peak(model, scene["contact"], scene["hb"], cc)
    t_peak = time.perf_counter() - t1
    static = _static_gaps(model, scene["contact"], vertex)
    t2 = time.perf_counter()
    worn = _worn_profile(model, scene, cc) if cc.wear else None
    t_wear = time.perf_counter() - t2
    L = scene["geometry"].axial_length
    row = {"nodes_along": int(na), "nodes_across": int(nc), "pairs": int(model.n_pairs),
           "h_contact_m": L / (na - 1), "dofs": info["dofs"], "tied_hz": pk["tied_hz"], "peak_hz": pk["peak_hz"],
           "peak_amplitude_m": pk["peak_amplitude_m"], "energy_J": pk["energy_J"],
           "max_wear_m": float(worn["W"].max()) if worn else None,
           "wear_steady": worn["steady"] if worn else None, "wear_hz": worn["frequency_hz"] if worn else None,
           "area_sum_rel_err": abs(float(model.area.sum()) - info["flank_area_m2"]) / info["flank_area_m2"],
           **static, "eps_n": pk["eps_n"], "eps_t": pk["eps_t"], "peak_evaluations": pk["evaluations"], "peak_at_band_edge": pk["at_band_edge"],
           "build_seconds": t_build, "peak_seconds": t_peak, "wear_seconds": t_wear,
           "seconds": time.perf_counter() - t0}
    log.info(f"contact mesh {na}×{nc}: {row['pairs']} pairs, {row['dofs']} DOFs; peak {row['peak_hz']:.4f} Hz "
             f"{row['peak_amplitude_m']:.5g} m, {row['energy_J']:.5g} J/cycle"
             + (f", max wear {row['max_wear_m']:.5g} m" if worn else "")
             + f"; midside gap min {static['midside_gap_min_m']}; {row['seconds']:.1f} s "
               f"(model {t_build:.1f}, peak {t_peak:.1f}, wear {t_wear:.1f})")
    return row, {"model": model, "W": worn["W"] if worn else None, "flank_area_m2": info["flank_area_m2"]}


def run(scene, inputs: dict, out: Path, log) -> dict:
    from workflow.io import write_npz, write_rows

    out = Path(out)
    cc = scene["contact_convergence"]
    work = out / "work"
    work.mkdir(parents=True, exist_ok=True)
    rows, raws = [], []
    for na, nc in zip(cc.nodes_along, cc.nodes_across):
        row, raw = run_level(scene, int(na), int(nc), work, log)
        rows.append(row)
        raws.append(raw)
        write_rows(out / CSV, rows)  # the table grows on disk as the study runs
    work.rmdir()
    profiles = None
    m0 = raws[0]["model"]
    points, pflank = common_points(np.asarray(m0.position), np.asarray(m0.flank), cc.profile_points)
    if cc.wear:
        profiles = np.array([profile_at(points, pflank, np.asarray(r["model"].position), np.asarray(r["model"].flank),
                                        r["W"]) for r in raws])
        write_npz(out / PROFILES, points=points, flank=pflank, W=profiles,
                  pairs=np.array([r["pairs"] for r in rows]))
    summary = summarise(rows, profiles)
    figures = plot(out, rows, points, pflank, profiles)
    log.info("contact convergence, two finest meshes: "
             + ", ".join(f"{k} {v:.3%}" for k, v in summary.items() if k.endswith("change_last") and v is not None))
    return {"rows": [{k: r[k] for k in ("pairs", "peak_hz", "peak_amplitude_m", "energy_J", "max_wear_m", "seconds")}
                     for r in rows],
            "table": rows, "layout": scene["geometry"].contact_nodes, "harmonics": int(cc.harmonics),
            "time_samples": int(cc.time_samples), **summary, "csv": CSV,
            "profiles": PROFILES if profiles is not None else None, "figures": figures}


# ------------------------------------------------------------------ figures

def plot(out: Path, rows: list[dict], points, pflank, profiles) -> list[str]:
    """``convergence.png`` (each quantity and its change to the finest mesh
    against the contact-mesh size) and ``profiles.png`` (worn profiles)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [("peak_hz", "peak frequency (Hz)"), ("peak_amplitude_m", "peak amplitude (m)"),
            ("energy_J", "energy per cycle at the peak (J)"), ("max_wear_m", "max wear depth (m)")]
    keys = [(k, lab) for k, lab in keys if all(r[k] is not None for r in rows)]
    h = np.array([r["h_contact_m"] for r in rows])
    fig, axs = plt.subplots(2, len(keys), figsize=(3.6 * len(keys), 6.4), squeeze=False)
    for j, (k, lab) in enumerate(keys):
        q = np.array([r[k] for r in rows], dtype=float)
        axs[0, j].plot(1e3 * h, q, "o-")
        axs[0, j].set_title(lab, fontsize=9)
        d = np.abs(q[:-1] - q[-1]) / abs(q[-1])
        axs[1, j].semilogy(1e3 * h[:-1], np.where(d > 0, d, np.nan), "s-")
        axs[1, j].set_title("|q − q_finest| / q_finest", fontsize=9)
        for ax in axs[:, j]:
            ax.invert_xaxis()  # finer meshes to the right
            ax.set_xlabel("flank element length along x (mm)")
            ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("contact-mesh convergence: " + ", ".join(f"{r['pairs']}" for r in rows) + " pairs")
    fig.tight_layout()
    files = [_save(fig, out / "convergence.png")]
    plt.close(fig)
    if profiles is not None:
        files.append(_plot_profiles(out / "profiles.png", rows, points, pflank, profiles))
    return [str(Path(f).relative_to(out)) for f in files]


def _plot_profiles(path: Path, rows, points, pflank, profiles) -> Path:
    """Worn profile along x on each flank, at the across-flank line of its maximum wear."""
    import matplotlib.pyplot as plt

    flanks = np.unique(pflank)
    fig, axs = plt.subplots(1, len(flanks), figsize=(6 * len(flanks), 4), squeeze=False)
    for j, f in enumerate(flanks):
        sel = np.flatnonzero(pflank == f)
        x = points[sel, 0]
        ax = axs[0, j]
        fin = profiles[-1, sel]
        line = np.isclose(np.linalg.norm(points[sel, 1:] - points[sel[np.argmax(fin)], 1:], axis=1), 0.0,
                          atol=1e-9)
        for r, W in zip(rows, profiles):
            o = np.argsort(x[line])
            ax.plot(1e3 * x[line][o], W[sel][line][o], ".-", label=f"{r['pairs']} pairs")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("wear depth W (m)")
        ax.set_title(f"flank {int(f)} ({'intrados' if f == 0 else 'extrados'}), line of max wear", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    p = _save(fig, path)
    plt.close(fig)
    return p


def _save(fig, path: Path) -> Path:
    from workflow.io import atomic_path

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    return path
