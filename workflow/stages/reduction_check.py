"""Reduction check stage: the reduced model against the full one (issue 3).

Eigenfrequencies and MAC with the interface tied and free, linear FRFs at
the observed DOFs over ±10 % around the first tied mode in both limits, and
their convergence with the number of fixed-interface modes against the wall
time of the reduction (:mod:`reduction.validate`). Writes
``convergence.csv``, ``convergence.png``, ``modes.csv`` (per mode, for the
reduced model of the ``reduced`` product) and ``frf.csv``.

The reduced model under test is the ``reduced`` product itself (frequencies,
FRFs); its MAC needs the basis, so it comes from the re-reduction with the
same settings in the convergence study (same code, same numbers).
"""
from __future__ import annotations

from pathlib import Path

NAME = "reduction_check"
SECTIONS = ("reduction",)
NEEDS = ("bundle", "reduced")
PRODUCES = ("reduction_check",)


def run(scene, inputs: dict, out: Path, log) -> dict:
    import numpy as np

    from reduction import validate as va
    from reduction.bundle import read_bundle
    from workflow.engine.model import ReducedModel
    from workflow.errors import BundleError
    from workflow.io import write_text
    from workflow.stages.assembly import bundle_folder
    from workflow.stages.reduction import REDUCED_FILE

    cfg = scene["reduction"]
    out = Path(out)
    bundle = read_bundle(bundle_folder(inputs["bundle"]))
    path = Path(inputs["reduced"]) / REDUCED_FILE
    if not path.is_file():
        raise BundleError(f"reduced model {path} is missing (the reduction stage writes it)")
    model = ReducedModel.load(path)
    ref = va.reference(bundle, cfg.check_modes, cfg.frf_points, log=log)

    kw = {} if model.info.get("modes_requested") else {"cutoff_hz": model.info.get("cutoff_hz") or None}
    counts = [c for c in cfg.check_mode_counts if c > 0]
    rows = va.convergence_study(bundle, counts, ref, log=log)
    if model.info.get("modes_requested"):
        counts_done = {r["modes"] for r in rows}
        if model.info["modes"] not in counts_done:
            rows += va.convergence_study(bundle, [model.info["modes"]], ref, log=log)
            rows.sort(key=lambda r: r["modes"])
        same = next(r for r in rows if r["modes"] == model.info["modes"])
    else:  # a cut-off: the study's counts cannot reproduce it; run it once more
        from reduction.reduce import reduce_with_basis

        _, basis = reduce_with_basis(bundle, None, **kw)
        same = va.evaluate(model, ref, basis)
    head = va.evaluate(model, ref)  # the saved model itself
    for key in ("tied", "free"):
        head[key]["mac"], head[key]["min_mac"] = same[key]["mac"], same[key]["min_mac"]

    va.write_table(rows, out / "convergence.csv")
    va.plot_convergence(rows, out / "convergence.png")
    va.write_modes_table(head, out / "modes.csv")
    H_t, H_f = va.reduced_frf(model, ref.omegas, True, ref.beta), va.reduced_frf(model, ref.omegas, False, ref.beta)
    lines = ["f_hz,obs,full_tied_abs,reduced_tied_abs,full_free_abs,reduced_free_abs"]
    for i, w in enumerate(ref.omegas):
        for j in range(H_t.shape[1]):
            lines.append(f"{w / 2 / np.pi:.6f},{j},{abs(ref.frf_tied[i, j]):.9e},{abs(H_t[i, j]):.9e},"
                         f"{abs(ref.frf_free[i, j]):.9e},{abs(H_f[i, j]):.9e}")
    write_text(out / "frf.csv", "\n".join(lines) + "\n")

    seconds = model.info.get("seconds", {})
    log.info(f"tied: max |Δf/f| {head['tied']['max_rel_freq_error']:.2e}, min MAC {head['tied']['min_mac']:.6f}; "
             f"free: max |Δf/f| {head['free']['max_rel_freq_error']:.2e}; FRF {head['frf_max_rel_error']:.2e}")
    brief = lambda r: {k: r[k] for k in ("max_rel_freq_error", "min_mac", "frf_max_rel_error", "rigid_skipped",
                                        "full_hz", "reduced_hz")}
    return {
        "modes": model.info.get("modes"),
        "boundary_dofs": model.info.get("boundary_dofs"),
        "size": model.size,
        "tied": brief(head["tied"]),
        "free": brief(head["free"]),
        "frf_max_rel_error": head["frf_max_rel_error"],
        "frf_band_hz": [float(ref.omegas[0] / 2 / np.pi), float(ref.omegas[-1] / 2 / np.pi)],
        "frf_extra_beta": ref.beta,
        "seconds": {"reduction": seconds.get("total"), "reduction_detail": seconds, **ref.seconds,
                    "study": {str(r["modes"]): r["seconds"] for r in rows}},
        "convergence": [va.flat_row(r) for r in rows],
        "table": "convergence.csv", "plot": "convergence.png", "modes_table": "modes.csv", "frf_table": "frf.csv",
    }
