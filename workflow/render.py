"""Off-screen pyvista figures of the wear: flank maps, the worn sector, mode shapes.

Works without a display (VTK's EGL/OSMesa through the PyPI wheel): every
figure is made by a ``pv.Plotter(off_screen=True)`` that is closed in a
``finally`` — VTK keeps render windows alive otherwise and memory grows from
figure to figure. PNGs go through :func:`workflow.io.atomic_path`.

Inputs are plain arrays (metres); wear is shown in micrometres. Flank
surfaces come as objects with ``points`` (k, 3), ``triangles`` (t, 3),
``wear`` (k,), ``normal`` (3,), ``contact`` (q, 3) and ``label`` — see
:class:`geometry.remap.FlankSurface`; the sector as a pyvista
``UnstructuredGrid`` built here from ``(cells, cell_types, points)`` as
returned by :func:`reduction.dolfinx_compat.vtk_mesh`, with ``body`` per cell.

**Process isolation.** Debian's dolfinx sets ``RTLD_GLOBAL`` at import and
never restores it; VTK libraries loaded afterwards then bind some C++
template symbols (``std::regex`` internals) to dolfinx's copies, and the
first scalar bar aborts the process (``std::bad_alloc`` in
``vtkScalarBarActor::LayoutTicks``). VTK loaded *before* dolfinx is fine.
So every public figure function here runs in-process only when VTK came
first (or dolfinx is absent), and otherwise in a fresh ``python`` child
that never imports dolfinx (arguments pickled; ~2 s of start-up).
"""
from __future__ import annotations

import functools
import os
import pickle
import subprocess
import sys
import tempfile
import types
from pathlib import Path

import numpy as np

from workflow.io import atomic_path

os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

#: Colour map of the wear depth (perceptually uniform, prints in grey).
CMAP = "viridis"
UM = 1e6  # m → µm
#: Where each scalar bar sits, as fractions of its renderer (x0, y0, width, height);
#: tests look for the bar's colours there.
BAR_BOX = (0.86, 0.12, 0.05, 0.76)
BACKGROUND = "white"


#: True once pyvista (VTK) is loaded in a process where dolfinx was not: safe in-process.
_VTK_FIRST: bool | None = None


def _pv():
    global _VTK_FIRST
    if _VTK_FIRST is None:
        _VTK_FIRST = "dolfinx.cpp" not in sys.modules
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def _must_isolate() -> bool:
    """Does a figure need a child process (dolfinx loaded before VTK here)?"""
    if _VTK_FIRST is not None:
        return not _VTK_FIRST
    return "dolfinx.cpp" in sys.modules


def _plain(obj):
    """Flank surfaces → namespaces of arrays, so the child needs no geometry/ import."""
    if isinstance(obj, (list, tuple)):
        return [_plain(o) for o in obj]
    if hasattr(obj, "triangles") and hasattr(obj, "points"):
        keys = ("points", "triangles", "wear", "normal", "contact", "label", "body")
        return types.SimpleNamespace(**{k: (np.asarray(getattr(obj, k)) if k not in ("label", "body")
                                            else str(getattr(obj, k)))
                                        for k in keys})
    return obj


def isolated(fn):
    """Run ``fn`` here when safe, else in a fresh interpreter (see the module doc)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        return together([(wrapper, args, kwargs)])[0]

    wrapper.inline = fn
    return wrapper


def together(calls) -> list:
    """Results of several figure calls ``[(function, args, kwargs), …]``, in order,
    made in one child process when isolation is needed (one ~2 s interpreter
    start for all of them instead of one each; the remap stage draws two maps)."""
    calls = [(getattr(f, "inline", f), a, dict(k)) for f, a, k in calls]
    if not _must_isolate():
        return [f(*a, **k) for f, a, k in calls]
    jobs = [(f.__name__, _plain(list(a)), {key: _plain(v) for key, v in k.items()}) for f, a, k in calls]
    with tempfile.TemporaryDirectory(prefix="bladewear-render-") as tmp:
        job = Path(tmp) / "job.pkl"
        job.write_bytes(pickle.dumps(jobs))
        root = str(Path(__file__).resolve().parents[1])
        env = dict(os.environ, PYVISTA_OFF_SCREEN="true",
                   PYTHONPATH=os.pathsep.join([root] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
        proc = subprocess.run([sys.executable, "-c", f"import workflow.render as r; r._child({str(job)!r})"],
                              env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            names = ", ".join(name for name, _, _ in jobs)
            raise RuntimeError(f"figure {names} failed in its render process:\n{proc.stderr[-3000:]}")
        return pickle.loads(job.with_suffix(".out").read_bytes())


def _child(job: str) -> None:
    """Entry point of the render process: run the figure functions, pickle their results."""
    jobs = pickle.loads(Path(job).read_bytes())
    out = [getattr(sys.modules[__name__], name).inline(*args, **kwargs) for name, args, kwargs in jobs]
    Path(job).with_suffix(".out").write_bytes(pickle.dumps(out))


def _bar_args(title: str, font: int) -> dict:
    x0, y0, w, h = BAR_BOX
    return dict(title=title, vertical=True, position_x=x0, position_y=y0, width=w, height=h, n_labels=5,
                fmt="%.3g", title_font_size=font, label_font_size=int(0.85 * font), color="black")


def _save(plotter, path: Path) -> Path:
    with atomic_path(path, suffix=".png") as tmp:
        plotter.screenshot(str(tmp))
    return Path(path)


def flank_frame(surface) -> tuple[np.ndarray, np.ndarray]:
    """(2, 3) in-plane axes (axial x projected on the flank, then across) and the
    origin of a flank surface, so that every map reads "axial →, across ↑"."""
    n = np.asarray(surface.normal, float)
    ex = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(ex) < 1e-6:  # a flank normal to x (not a dovetail slot): any in-plane axis
        ex = np.cross(n, [0.0, 0.0, 1.0])
    ex /= np.linalg.norm(ex)
    ey = np.cross(n, ex)
    if ey[2] < 0:  # "across" reads upwards (radially outwards)
        ey = -ey
    return np.stack([ex, ey]), surface.points.min(axis=0)


@isolated
def render_flank_wear(surfaces, path, width: int = 1600, clim=None, title: str = "") -> Path:
    """One row per flank: its wear depth [µm] on the flank plane (axial x to the
    right, across the flank upwards), contact nodes as dots, a labelled colour
    bar per row (the same range for all rows, so colours compare)."""
    pv = _pv()
    surfaces = list(surfaces)
    if not surfaces:
        raise ValueError("render_flank_wear: no flank surfaces")
    wmax = max(float(np.max(s.wear)) for s in surfaces) * UM
    clim = clim or (0.0, wmax if wmax > 0 else 1.0)
    row_h = int(0.3 * width)
    font = max(12, width // 70)
    plotter = pv.Plotter(off_screen=True, shape=(len(surfaces), 1), window_size=(width, row_h * len(surfaces)),
                         border=False)
    try:
        plotter.set_background(BACKGROUND)
        for i, s in enumerate(surfaces):
            plotter.subplot(i, 0)
            axes, origin = flank_frame(s)
            uv = (s.points - origin) @ axes.T
            poly = pv.PolyData(np.column_stack([uv, np.zeros(len(uv))]),
                               np.hstack([np.full((len(s.triangles), 1), 3), s.triangles]).ravel())
            poly.point_data["wear"] = s.wear * UM
            plotter.add_mesh(poly, scalars="wear", cmap=CMAP, clim=clim, show_edges=True, edge_color="grey",
                             line_width=0.5, show_scalar_bar=False, lighting=False)
            # pyvista keeps one bar per title: pad the title so each row has its own.
            plotter.add_scalar_bar(mapper=plotter.mapper, **_bar_args("wear depth [µm]" + " " * i, font))
            cuv = (np.asarray(s.contact) - origin) @ axes.T
            if len(cuv):
                plotter.add_points(np.column_stack([cuv, np.full(len(cuv), 1e-9)]), color="black",
                                   point_size=max(4, width // 250), render_points_as_spheres=True)
            label = s.label + (f": max {np.max(s.wear) * UM:.3g} µm" if np.max(s.wear) > 0 else ": unworn")
            plotter.add_text(label, position="upper_left", font_size=int(0.6 * font), color="black")
            _fit_strip(plotter, uv, width / row_h)
        plotter.subplot(len(surfaces) - 1, 0)
        plotter.add_text(title or "axial x: left (leading edge) to right; across the flank: upwards (outer end)",
                         position="lower_left", font_size=int(0.45 * font), color="black")
        return _save(plotter, path)
    finally:
        plotter.close()


def _fit_strip(plotter, uv: np.ndarray, aspect: float, left: float = 0.04, right: float = 0.80,
               bottom: float = 0.12, top: float = 0.82) -> None:
    """Parallel camera looking down z that fits the 2-D points ``uv`` into the
    viewport box [left, right] × [bottom, top] (fractions), clear of the colour
    bar on the right and the title on top."""
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    span = np.maximum(hi - lo, 1e-12)
    # parallel_scale = half the visible height [m]; visible width = aspect × height.
    scale = max(span[1] / (top - bottom), span[0] / ((right - left) * aspect)) / 2.0
    vis_w, vis_h = 2.0 * scale * aspect, 2.0 * scale
    # The strip's lower-left corner sits at (left, bottom) plus half the slack of the box.
    cx = lo[0] - left * vis_w - 0.5 * ((right - left) * vis_w - span[0]) + 0.5 * vis_w
    cy = lo[1] - bottom * vis_h - 0.5 * ((top - bottom) * vis_h - span[1]) + 0.5 * vis_h
    cam = plotter.camera
    cam.parallel_projection = True
    cam.focal_point = (cx, cy, 0.0)
    cam.position = (cx, cy, 1.0)
    cam.up = (0.0, 1.0, 0.0)
    cam.parallel_scale = scale
    cam.clipping_range = (0.5, 1.5)


def sector_grid(cells, cell_types, points, body: np.ndarray | None = None, wear: np.ndarray | None = None):
    """A pyvista ``UnstructuredGrid`` of the sector (``vtk_mesh`` output) with cell
    data ``body`` (1 blade, 2 disk) and point data ``wear [µm]`` (from metres)."""
    pv = _pv()
    grid = pv.UnstructuredGrid(np.asarray(cells), np.asarray(cell_types), np.asarray(points, dtype=float))
    grid.cell_data["body"] = np.ones(grid.n_cells, dtype=int) if body is None else np.asarray(body)
    grid.point_data["wear [µm]"] = (np.zeros(grid.n_points) if wear is None else np.asarray(wear) * UM)
    return grid


@isolated
def render_sector(cells, cell_types, points, body, surfaces, path, width: int = 1600, clim=None, title: str = "",
                  explode: float = 1.15) -> Path:
    """The whole sector with its worn zones: blade (blue-grey) pulled axially out
    of the disk (grey) by ``explode`` × the model's axial length so both sides of
    every flank show, each flank coloured by its wear depth [µm]. Two views,
    from the extrados (+y) and the intrados (−y) side, one colour bar.

    ``cells, cell_types, points``: the mesh as from ``dolfinx_compat.vtk_mesh``
    (points in m); ``body`` (n_cells,) 1 blade / 2 disk."""
    pv = _pv()
    surfaces = list(surfaces)
    grid = sector_grid(cells, cell_types, points, body)
    wmax = max([float(np.max(s.wear)) for s in surfaces] + [0.0]) * UM
    clim = clim or (0.0, wmax if wmax > 0 else 1.0)
    font = max(12, width // 70)
    pts = np.asarray(points, dtype=float)
    shift = np.array([explode * (pts[:, 0].max() - pts[:, 0].min()), 0.0, 0.0])
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(width, int(0.5 * width)), border=False)
    try:
        plotter.set_background(BACKGROUND)
        cell_body = np.asarray(grid.cell_data["body"])
        parts = {tag: grid.extract_cells(np.flatnonzero(cell_body == tag)).extract_surface(algorithm="dataset_surface") for tag in (1, 2)}
        parts[1].points = np.asarray(parts[1].points) + shift
        for col, (side, view) in enumerate((("extrados side (+y)", (-0.7, 1.0, 0.35)),
                                            ("intrados side (−y)", (-0.7, -1.0, 0.35)))):
            plotter.subplot(0, col)
            for tag, colour in ((1, "lightsteelblue"), (2, "gainsboro")):
                if parts[tag].n_cells:
                    plotter.add_mesh(parts[tag], color=colour, show_scalar_bar=False)
            for s in surfaces:
                blade = getattr(s, "body", "blade") == "blade"
                # Lift each flank a hair off its body's surface along the body's outward
                # normal (−n on the blade, +n on the disk) so it is drawn on top.
                lift = (-1.0 if blade else 1.0) * 2e-3 * size * np.asarray(s.normal, float)
                poly = pv.PolyData(np.asarray(s.points, float) + lift + (shift if blade else 0.0),
                                   np.hstack([np.full((len(s.triangles), 1), 3), s.triangles]).ravel())
                poly.point_data["wear"] = s.wear * UM
                plotter.add_mesh(poly, scalars="wear", cmap=CMAP, clim=clim, show_scalar_bar=False,
                                 lighting=False)
            plotter.add_text(side, position="upper_left", font_size=int(0.55 * font), color="black")
            plotter.view_vector(view, viewup=(0.0, 0.0, 1.0))
            plotter.reset_camera()
            plotter.camera.zoom(1.25)
            if col == 1 and surfaces:
                plotter.add_scalar_bar(mapper=plotter.mapper, **_bar_args("wear depth [µm]", font))
        plotter.subplot(0, 0)
        plotter.add_text(title or "worn zones: flanks coloured by wear depth (blade pulled out axially)",
                         position="lower_left", font_size=int(0.5 * font), color="black")
        return _save(plotter, path)
    finally:
        plotter.close()


@isolated
def render_mode_shape(cells, cell_types, points, displacement: np.ndarray, path, width: int = 1600,
                      scale: float | None = None, title: str = "", camera=(-1.0, 1.2, 0.7)) -> Path:
    """The sector deformed by ``displacement`` (n_points, 3) [m], e.g. a mode or
    the response at resonance, coloured by its magnitude; ``scale`` defaults to
    10 % of the model's size over the largest displacement."""
    pv = _pv()
    grid = sector_grid(cells, cell_types, points)
    d = np.asarray(displacement, dtype=float)
    mag = np.linalg.norm(d, axis=1)
    if scale is None:
        scale = 0.1 * grid.length / mag.max() if mag.max() > 0 else 0.0
    g = grid.copy()
    g.point_data["|u|"] = mag
    g.points = np.asarray(grid.points) + scale * d
    font = max(12, width // 70)
    plotter = pv.Plotter(off_screen=True, window_size=(width, int(0.75 * width)))
    try:
        plotter.set_background(BACKGROUND)
        plotter.add_mesh(grid.extract_surface(algorithm="dataset_surface"), style="wireframe", color="grey", opacity=0.15)
        plotter.add_mesh(g.extract_surface(algorithm="dataset_surface"), scalars="|u|", cmap="plasma", show_scalar_bar=False)
        plotter.add_scalar_bar(mapper=plotter.mapper, **_bar_args("displacement magnitude", font))
        plotter.add_text(title or f"deformed shape (×{scale:.3g})", position="upper_left",
                         font_size=int(0.6 * font), color="black")
        plotter.view_vector(camera)
        return _save(plotter, path)
    finally:
        plotter.close()
