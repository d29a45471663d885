"""The 3D wear view two ways, measured: our page (``wear_3d.html``) against pyvista's HTML export.

Issue 21 asks to choose the report's interactive view "by measurement (file
size, load time)". Two steps, because pyvista's ``Plotter.export_html``
needs ``trame`` and ``trame-vtk``, which the project does not depend on:

``export`` (run with a Python that has pyvista + trame, e.g. a scratch venv)
    reads the arrays of a run's ``wear_3d.html`` (:func:`workflow.report.
    viewer3d.read_viewer`: the same triangles, the blade pulled out as the page
    shows it first) and writes ``pyvista_export.html``: the bodies in their
    colours, the flanks with a ``wear [µm]`` scalar (recovered from the
    page's viridis colours, within 1/255 of the colour bar's top) and a
    scalar bar.
``measure`` (the project's venv)
    opens each page from disk in headless Chromium through the DevTools
    protocol (``--remote-debugging-pipe``: no extra package), with the
    network emulated offline and every host unresolvable, and records: file
    size, time from navigation to the first WebGL draw call and to the frame
    after it (a probe wraps ``drawArrays``/``drawElements``; the same probe
    for both pages), every network request that is not ``file:``/``data:``/
    ``blob:``, console errors and uncaught exceptions, and the share of
    non-white pixels of a screenshot taken after the frame. Writes
    ``viewer3d_compare.json`` and ``.md``.

    python -m workflow.bench.viewer3d_compare measure results/demo/report/wear_3d.html \\
        /tmp/pyvista_export.html --runs 5 --out results/bench/viewer3d
"""
from __future__ import annotations

import argparse
import base64
import io
import json
import time
from pathlib import Path

import numpy as np

from workflow.bench.cdp import Chromium

LOCAL = ("file:", "data:", "blob:", "about:", "chrome")
BENIGN = ("GL Driver Message", "GPU stall due to ReadPixels", "Automatic fallback to software WebGL")
#: Injected before any page script: the first WebGL draw call and the frame after it [ms since navigation].
PROBE = """(() => {
  const p = window.__probe = {firstDraw: null, frame: null, draws: 0, glStart: null, glReady: null};
  const getContext = HTMLCanvasElement.prototype.getContext;
  HTMLCanvasElement.prototype.getContext = function (kind, ...a) {
    const webgl = String(kind).startsWith("webgl");
    if (webgl && p.glStart === null) p.glStart = performance.now();
    const ctx = getContext.call(this, kind, ...a);
    if (webgl && p.glReady === null) p.glReady = performance.now();
    return ctx;
  };
  for (const C of [window.WebGLRenderingContext, window.WebGL2RenderingContext]) {
    if (!C) continue;
    for (const name of ["drawArrays", "drawElements", "drawArraysInstanced", "drawElementsInstanced"]) {
      const f = C.prototype[name];
      if (!f) continue;
      C.prototype[name] = function (...a) {
        p.draws++;
        if (p.firstDraw === null) { p.firstDraw = performance.now();
          requestAnimationFrame(() => { p.frame = performance.now(); }); }
        return f.apply(this, a);
      };
    }
  }
})();"""


def export_pyvista(page: Path, out: Path) -> Path:
    """pyvista's ``export_html`` of the data of our page ``page`` (needs pyvista, trame, trame-vtk)."""
    import pyvista as pv
    from matplotlib import colormaps

    from workflow.report.viewer3d import BODY_COLOURS, read_viewer

    d = read_viewer(page)
    pos = d["positions"].astype(float).copy()
    blade = d["part"] % 2 == 1
    pos[blade, 0] += 1.15 * np.ptp(pos[:, 0])  # the page's first view: blade pulled out axially
    tri = d["triangles"].astype(np.int64)
    part_of_tri = d["part"][tri[:, 0]]
    lut = (colormaps["viridis"](np.linspace(0, 1, 256))[:, :3] * 255).astype(float)
    plotter = pv.Plotter(off_screen=True, window_size=(1000, 700))
    for flag, name in ((1, "blade"), (0, "disk")):
        t = tri[part_of_tri == flag]
        plotter.add_mesh(_poly(pv, pos, t), color=BODY_COLOURS[1 if flag else 2], name=name)
    t = tri[part_of_tri >= 2]
    mesh = _poly(pv, pos, t)
    rgb = d["colours"][mesh["vid"]].astype(float)
    mesh["wear [µm]"] = np.argmin(((rgb[:, None] - lut[None]) ** 2).sum(-1), axis=1) / 255.0 * d["wear_max_um"]
    plotter.add_mesh(mesh, scalars="wear [µm]", cmap="viridis", clim=(0, d["wear_max_um"]), name="flanks")
    # The page's first view: from the side of the deepest-worn flank, at the flanks' box (viewer3d.html, `home`).
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    yaw, pitch, centre = np.arctan2(d["view_side"], -0.7), 0.35, 0.5 * (lo + hi)
    eye = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    plotter.camera_position = [tuple(centre + 3.2 * 0.5 * np.linalg.norm(hi - lo) * eye), tuple(centre), (0, 0, 1)]
    print(f"flank wear {mesh['wear [µm]'].min():.3g}…{mesh['wear [µm]'].max():.3g} µm on {mesh.n_cells} triangles, "
          f"{len(tri)} triangles in all")
    plotter.export_html(str(out))
    plotter.close()
    return Path(out)


def _poly(pv, pos, tri):
    used, local = np.unique(tri, return_inverse=True)
    faces = np.hstack([np.full((len(tri), 1), 3), local.reshape(-1, 3)]).ravel()
    mesh = pv.PolyData(pos[used], faces)
    mesh["vid"] = used
    return mesh


def open_page(page: Path, shot_path: Path | None = None, settle_s: float = 1.0, timeout_s: float = 30.0) -> dict:
    """One cold load of ``page`` from disk (fresh browser, network offline): times, requests, errors, pixels."""
    br = Chromium()
    try:
        for domain in ("Page", "Runtime", "Network", "Log"):
            br.call(f"{domain}.enable")
        br.call("Network.emulateNetworkConditions", offline=True, latency=0, downloadThroughput=-1,
                uploadThroughput=-1)
        br.call("Page.addScriptToEvaluateOnNewDocument", source=PROBE)
        br.call("Page.navigate", url=Path(page).resolve().as_uri())
        end, probe = time.monotonic() + timeout_s, {}
        while time.monotonic() < end:
            probe = br.call("Runtime.evaluate", expression="JSON.stringify(window.__probe||{})",
                            returnByValue=True)["result"].get("value") or "{}"
            probe = json.loads(probe)
            if probe.get("frame") is not None:
                break
            time.sleep(0.05)
        time.sleep(settle_s)
        shot = base64.b64decode(br.call("Page.captureScreenshot", format="png")["data"])
        probe = json.loads(br.call("Runtime.evaluate", expression="JSON.stringify(window.__probe)",
                                   returnByValue=True)["result"]["value"])
    finally:
        br.close()
    if shot_path is not None:
        Path(shot_path).write_bytes(shot)
    return {"first_draw_ms": probe.get("firstDraw"), "first_frame_ms": probe.get("frame"),
            "webgl_context_ms": [probe.get("glStart"), probe.get("glReady")],
            "draw_calls": probe.get("draws"), "requests": _requests(br.events), "errors": _errors(br.events),
            "drawn_fraction": _drawn(shot)}


def _requests(events) -> list[str]:
    return [e["params"]["request"]["url"][:120] for e in events if e.get("method") == "Network.requestWillBeSent"
            and not e["params"]["request"]["url"].startswith(LOCAL)]


def _errors(events) -> list[str]:
    out = []
    for e in events:
        m, p = e.get("method"), e.get("params", {})
        if m == "Runtime.exceptionThrown":
            out.append(p["exceptionDetails"].get("exception", {}).get("description", p["exceptionDetails"]["text"]))
        elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "warning", "assert"):
            out.append(" ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", [])))
        elif m == "Log.entryAdded" and p["entry"]["level"] in ("error", "warning"):
            out.append(p["entry"]["text"])
    return [x[:200] for x in out if not any(b in x for b in BENIGN)]


def _drawn(png: bytes) -> float:
    """Share of the screenshot's pixels that are not (near) white."""
    import matplotlib.image as mpimg

    img = mpimg.imread(io.BytesIO(png), format="png")[..., :3]
    return float((img < 245 / 255).any(axis=2).mean())


def measure(pages: list[Path], runs: int, shots: Path | None = None) -> list[dict]:
    """Per page: size [MB] and ``runs`` cold loads (median and range of the times [ms]),
    interleaved over the pages so that a change of machine load hits both alike;
    the last load's screenshot goes to ``shots/<page stem>.png``."""
    loads = {p: [] for p in pages}
    for i in range(runs):
        for page in pages:
            shot = Path(shots) / f"{Path(page).stem}.png" if shots is not None and i == runs - 1 else None
            loads[page].append(open_page(page, shot))
    return [summarise(page, loads[page]) for page in pages]


def summarise(page: Path, loads: list[dict]) -> dict:
    """One page's row: size [MB], median and range of the times [ms], requests, errors, drawn pixels."""
    def med(key):
        v = [x[key] for x in loads if x[key] is not None]
        return (float(np.median(v)), [min(v), max(v)]) if v else (None, None)

    frame, draw, gl = med("first_frame_ms"), med("first_draw_ms"), [x["webgl_context_ms"][1] for x in loads]
    return {"page": str(page), "size_mb": Path(page).stat().st_size / 1e6, "runs": len(loads),
            "first_frame_ms_median": frame[0], "first_frame_ms_range": frame[1], "first_draw_ms_median": draw[0],
            "webgl_context_ready_ms_median": float(np.median([g for g in gl if g is not None] or [np.nan])),
            # the page's own work: from its WebGL context to its first frame (the rest is Chromium's GL start-up)
            "page_work_ms_median": float(np.median([x["first_frame_ms"] - x["webgl_context_ms"][1] for x in loads
                                                    if x["first_frame_ms"] is not None
                                                    and x["webgl_context_ms"][1] is not None] or [np.nan])),
            "requests": sorted({r for x in loads for r in x["requests"]}),
            "errors": sorted({r for x in loads for r in x["errors"]}),
            "drawn_fraction_min": min(x["drawn_fraction"] for x in loads), "loads": loads}


def table(rows: list[dict]) -> str:
    """The comparison as a Markdown table."""
    lines = ["| page | size [MB] | navigation → first frame [ms], median (range) | WebGL context ready at [ms] | "
             "context → first frame [ms] | network requests (offline) | console errors | drawn pixels [%] |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        rng = r["first_frame_ms_range"]
        t = "never drew" if rng is None else f"{r['first_frame_ms_median']:.0f} ({rng[0]:.0f}–{rng[1]:.0f})"
        lines.append(f"| `{Path(r['page']).name}` | {r['size_mb']:.3g} | {t} | {r['webgl_context_ready_ms_median']:.0f} | "
                     f"{r['page_work_ms_median']:.0f} | "
                     f"{len(r['requests'])} | "
                     f"{len(r['errors'])} | {100 * r['drawn_fraction_min']:.0f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m workflow.bench.viewer3d_compare", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    ex = sub.add_parser("export", help="pyvista export_html of a wear_3d.html's data (needs pyvista + trame)")
    ex.add_argument("page", type=Path)
    ex.add_argument("--out", type=Path, required=True)
    me = sub.add_parser("measure", help="size, load time, offline behaviour of HTML pages in headless Chromium")
    me.add_argument("pages", type=Path, nargs="+")
    me.add_argument("--runs", type=int, default=5)
    me.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    if a.cmd == "export":
        print(export_pyvista(a.page, a.out))
        return
    a.out.mkdir(parents=True, exist_ok=True)
    rows = measure(a.pages, a.runs, shots=a.out)
    (a.out / "viewer3d_compare.json").write_text(json.dumps(rows, indent=1))
    (a.out / "viewer3d_compare.md").write_text(table(rows))
    print(table(rows))


if __name__ == "__main__":
    main()
