"""Off-screen pyvista figures of the wear: flank maps, the worn sector, mode shapes.

Works without a display (VTK's EGL/OSMesa through the PyPI wheel): every
figure is made by a ``pv.Plotter(off_screen=True)`` that is closed in a
``finally`` — VTK keeps render windows alive otherwise and memory grows from
figure to figure. PNGs go through :func:`workflow.io.atomic_path`.

Inputs are plain arrays (metres); wear is shown in micrometres. Flank
surfaces come as objects with ``points`` (k, 3), ``triangles`` (t, 3),
``wear`` (k,), ``normal`` (3,), ``contact`` (q, 3) and ``label`` — see
:class:`geometry.remap.FlankSurface`; the sector as a pyvista
``UnstructuredGrid`` (built from the dolfinx mesh with
:func:`reduction.dolfinx_compat.vtk_mesh`) with cell data ``body``.
"""
from __future__ import annotations

import os
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


def _pv():
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


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


def render_flank_wear(surfaces, path, width: int = 1600, clim=None, title: str = "") -> Path:
    """One row per flank: its wear depth [µm] on the flank plane (axial → across),
    contact nodes as dots, a labelled colour bar per row (same range for all)."""
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
            poly.point_data["wear [µm]"] = s.wear * UM
            plotter.add_mesh(poly, scalars="wear [µm]", cmap=CMAP, clim=clim, show_edges=True, edge_color="grey",
                             line_width=0.5, show_scalar_bar=False, lighting=False)
            plotter.add_scalar_bar(mapper=plotter.mapper, **_bar_args("wear depth [µm]", font))
            cuv = (np.asarray(s.contact) - origin) @ axes.T
            if len(cuv):
                plotter.add_points(np.column_stack([cuv, np.full(len(cuv), 1e-9)]), color="black",
                                   point_size=max(4, width // 250), render_points_as_spheres=True)
            label = s.label + (f" — max {np.max(s.wear) * UM:.3g} µm" if np.max(s.wear) > 0 else " — unworn")
            plotter.add_text(label, position="upper_left", font_size=int(0.6 * font), color="black")
            plotter.add_text("axial x →", position="lower_left", font_size=int(0.5 * font), color="black")
            plotter.view_xy()
            plotter.enable_parallel_projection()
            plotter.camera.zoom(0.82)  # keep the strip clear of the colour bar
        if title:
            plotter.subplot(0, 0)
            plotter.add_text(title, position="upper_edge", font_size=int(0.6 * font), color="black")
        return _save(plotter, path)
    finally:
        plotter.close()


def sector_grid(cells, cell_types, points, body: np.ndarray, wear: np.ndarray | None = None):
    """A pyvista ``UnstructuredGrid`` of the sector (``vtk_mesh`` output) with cell
    data ``body`` (1 blade, 2 disk) and point data ``wear [µm]`` (from metres)."""
    pv = _pv()
    grid = pv.UnstructuredGrid(np.asarray(cells), np.asarray(cell_types), np.asarray(points, dtype=float))
    grid.cell_data["body"] = np.asarray(body)
    grid.point_data["wear [µm]"] = (np.zeros(grid.n_points) if wear is None else np.asarray(wear) * UM)
    return grid


def render_sector(grid, surfaces, path, width: int = 1600, clim=None, title: str = "",
                  camera=(-1.0, 1.2, 0.7)) -> Path:
    """The whole sector: blade grey, disk translucent, every flank coloured by its
    wear depth [µm] with a colour bar — the worn zones stand out."""
    pv = _pv()
    surfaces = list(surfaces)
    wmax = max([float(np.max(s.wear)) for s in surfaces] + [0.0]) * UM
    clim = clim or (0.0, wmax if wmax > 0 else 1.0)
    font = max(12, width // 70)
    plotter = pv.Plotter(off_screen=True, window_size=(width, int(0.75 * width)))
    try:
        plotter.set_background(BACKGROUND)
        body = np.asarray(grid.cell_data["body"])
        for tag, colour, opacity in ((1, "lightsteelblue", 1.0), (2, "lightgrey", 0.35)):
            part = grid.extract_cells(np.flatnonzero(body == tag))
            if part.n_cells:
                plotter.add_mesh(part.extract_surface(), color=colour, opacity=opacity, smooth_shading=False,
                                 show_scalar_bar=False)
        for s in surfaces:
            poly = pv.PolyData(np.asarray(s.points, float),
                               np.hstack([np.full((len(s.triangles), 1), 3), s.triangles]).ravel())
            poly.point_data["wear [µm]"] = s.wear * UM
            plotter.add_mesh(poly, scalars="wear [µm]", cmap=CMAP, clim=clim, show_scalar_bar=False,
                             lighting=False)
        if surfaces:
            plotter.add_scalar_bar(mapper=plotter.mapper, **_bar_args("wear depth [µm]", font))
        plotter.add_text(title or "worn zones of the sector (flanks coloured by wear depth)",
                         position="upper_left", font_size=int(0.6 * font), color="black")
        plotter.view_vector(camera)
        plotter.camera.zoom(1.1)
        plotter.add_axes(color="black")
        return _save(plotter, path)
    finally:
        plotter.close()


def render_mode_shape(grid, displacement: np.ndarray, path, width: int = 1600, scale: float | None = None,
                      title: str = "", camera=(-1.0, 1.2, 0.7)) -> Path:
    """The sector deformed by ``displacement`` (n_points, 3) [m], e.g. a mode or
    the response at resonance, coloured by its magnitude; ``scale`` defaults to
    10 % of the model's size over the largest displacement."""
    pv = _pv()
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
        plotter.add_mesh(grid.extract_surface(), style="wireframe", color="grey", opacity=0.15)
        plotter.add_mesh(g.extract_surface(), scalars="|u|", cmap="plasma", show_scalar_bar=False)
        plotter.add_scalar_bar(mapper=plotter.mapper, **_bar_args("|u| (relative)", font))
        plotter.add_text(title or f"deformed shape (×{scale:.3g})", position="upper_left",
                         font_size=int(0.6 * font), color="black")
        plotter.view_vector(camera)
        return _save(plotter, path)
    finally:
        plotter.close()
