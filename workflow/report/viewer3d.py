"""A self-contained interactive 3D page of the worn sector: one HTML file, no network.

The page carries the sector's outer surface (blade and disk) and every flank
coloured by its wear depth as base64 typed arrays, and a ~150-line WebGL2
viewer (drag to turn, wheel to zoom, blade pulled out of the disk, disk
hidden). It opens from disk in any current browser (``file://``), without a
server, a CDN or a Python package beyond NumPy and matplotlib (for the
colour map).

Why not ``pyvista.Plotter.export_html``: measured on the quick scene with
the same triangles (``workflow/bench/viewer3d_compare.py``, docs/report.md),
its page is 1.08 MB (vtk.js) against 0.05 MB here, needs ~0.3 s of its
own work after its WebGL context against ~0.05–0.08 s here (the first
frame itself comes 0.8–1.1 s after navigation for both in headless Chromium
with software WebGL, most of it Chromium's GL start-up), asks the network
for five favicons when opened offline, and needs trame, trame-vtk,
trame-vuetify, trame-pyvista and nest_asyncio2, which the project does not
depend on. Its colour bar (ticks, title) is the better one.

Units: positions are drawn in millimetres (metres in, ×1e3); wear in
micrometres (metres in, ×1e6).
"""
from __future__ import annotations

import base64
import html
import json
from pathlib import Path

import numpy as np

from workflow.errors import GeometryError
from workflow.io import write_text

UM, MM = 1e6, 1e3
#: VTK cell types with the four corners first: linear (10), quadratic (24) and
#: Lagrange (71, what dolfinx gives for a quadratic-geometry mesh) tetrahedra.
TET_TYPES = (10, 24, 71)
#: Tetrahedron faces by local corner index, outward-consistent for positive volume.
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
BODY_COLOURS = {1: (0.69, 0.77, 0.87), 2: (0.84, 0.84, 0.84)}  # blade light steel blue, disk light grey


def tet_corners(cells: np.ndarray, cell_types: np.ndarray) -> np.ndarray:
    """Corner node indices (n_cells, 4) of a VTK cell array of tetrahedra.

    ``cells`` is VTK's flat ``[n, i0, …, i(n−1), n, …]`` layout as returned by
    ``dolfinx.plot.create_vtk_mesh``; every cell must be a tetrahedron of one
    order (the gmsh sector is), whose first four nodes are the corners;
    otherwise :class:`~workflow.errors.GeometryError`.
    """
    cells, cell_types = np.asarray(cells, dtype=np.int64), np.asarray(cell_types)
    if cell_types.size == 0:
        return np.zeros((0, 4), dtype=np.int64)
    if not np.isin(cell_types, TET_TYPES).all():
        raise GeometryError(f"3D view: cell types {sorted(set(cell_types.tolist()) - set(TET_TYPES))} "
                         f"are not tetrahedra")
    width = int(cells[0]) + 1
    table = cells.reshape(-1, width)
    return table[:, 1:5]


def boundary_triangles(corners: np.ndarray) -> np.ndarray:
    """Triangles (t, 3) of the faces that belong to exactly one tetrahedron of
    ``corners`` (n, 4): the closed outer surface of that set of cells."""
    faces = corners[:, TET_FACES].reshape(-1, 3)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def viridis_rgb(values: np.ndarray, vmax: float) -> np.ndarray:
    """uint8 RGB (k, 3) of ``values`` on matplotlib's viridis over [0, vmax]."""
    from matplotlib import colormaps

    t = np.clip(np.asarray(values, dtype=float) / vmax, 0.0, 1.0) if vmax > 0 else np.zeros(len(values))
    return (colormaps["viridis"](t)[:, :3] * 255.0 + 0.5).astype(np.uint8)


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def scene_arrays(points: np.ndarray, corners: np.ndarray, body: np.ndarray, surfaces) -> dict:
    """Vertex arrays of the view: positions (v, 3) float32 [mm, centred],
    colours (v, 3) uint8, part (v,) uint8 (bit 0: blade, pulled out of the
    disk on request; bit 1: a flank), triangles (t, 3) uint32, and the wear range [µm].

    ``points`` (n, 3) [m]; ``corners`` (c, 4) tetrahedra; ``body`` (c,) 1
    blade / 2 disk; ``surfaces`` flank surfaces (``points`` [m],
    ``triangles``, ``wear`` [m], ``normal``, ``body``) as
    :class:`geometry.remap.FlankSurface`.
    """
    points = np.asarray(points, dtype=float)
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    size = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    surfaces = list(surfaces)
    wmax = max([float(np.max(s.wear)) for s in surfaces if len(s.wear)] + [0.0])
    pos, col, part, tri = [], [], [], []
    n = 0

    def add(p, c, blade, t):
        nonlocal n
        pos.append(p)
        col.append(c)
        part.append(np.full(len(p), 1 if blade else 0, dtype=np.uint8))
        tri.append(np.asarray(t, dtype=np.int64) + n)
        n += len(p)

    for tag in (1, 2):
        faces = boundary_triangles(corners[np.asarray(body) == tag])
        used, local = np.unique(faces, return_inverse=True)
        rgb = np.tile((np.array(BODY_COLOURS[tag]) * 255).astype(np.uint8), (len(used), 1))
        add(points[used], rgb, tag == 1, local.reshape(-1, 3))
    for s in surfaces:
        blade = getattr(s, "body", "blade") == "blade"
        # Lift each flank off its body along the body's outward normal (−n on the
        # blade, +n on the disk) so it is drawn over the coincident body face.
        lift = (-1.0 if blade else 1.0) * 2e-3 * size * np.asarray(s.normal, dtype=float)
        add(np.asarray(s.points, dtype=float) + lift, viridis_rgb(s.wear, wmax), blade, s.triangles)
        part[-1] += 2  # flag: a flank (drawn unlit, framed by the initial view)
    # Look first from the side the most worn blade flank faces (its outward normal is −n).
    deepest = max(surfaces, key=lambda s: float(np.max(s.wear)) if len(s.wear) else 0.0, default=None)
    side = -np.sign(deepest.normal[1]) if deepest is not None and deepest.normal[1] != 0 else 1.0
    return {"positions": ((np.vstack(pos) - centre) * MM).astype(np.float32), "view_side": float(side),
            "colours": np.vstack(col).astype(np.uint8), "part": np.concatenate(part),
            "triangles": np.vstack(tri).astype(np.uint32), "wear_max_um": wmax * UM,
            "size_mm": size * MM}


def colourbar_css() -> str:
    """A CSS linear-gradient of viridis (11 stops), for the page's colour bar."""
    stops = viridis_rgb(np.linspace(0.0, 1.0, 11), 1.0)
    return "linear-gradient(to right," + ",".join(f"rgb({r},{g},{b}) {10 * i}%"
                                                  for i, (r, g, b) in enumerate(stops)) + ")"


def write_viewer(path, points, cells, cell_types, body, surfaces, title: str, note: str = "") -> Path:
    """Write the self-contained viewer page to ``path`` (atomically) and return it.

    ``points`` [m], ``cells``/``cell_types`` VTK layout, ``body`` per cell
    (1 blade, 2 disk), ``surfaces`` the flank surfaces with wear [m];
    ``note`` a line under the title (e.g. where the wear is deepest).
    """
    arr = scene_arrays(points, tet_corners(cells, cell_types), body, surfaces)
    data = {"positions": _b64(arr["positions"]), "colours": _b64(arr["colours"]), "part": _b64(arr["part"]),
            "triangles": _b64(arr["triangles"]), "n_triangles": int(len(arr["triangles"])),
            "size_mm": arr["size_mm"], "view_side": arr["view_side"]}
    page = (_TEMPLATE.replace("__TITLE__", html.escape(title)).replace("__NOTE__", html.escape(note))
            .replace("__WMAX__", f"{arr['wear_max_um']:.3g}").replace("__BAR__", colourbar_css())
            .replace("__DATA__", json.dumps(data)))
    return write_text(path, page)


_TEMPLATE = Path(__file__).with_name("viewer3d.html").read_text()


def read_viewer(path) -> dict:
    """The arrays a page of :func:`write_viewer` carries, decoded: ``positions``
    (v, 3) float32 [mm], ``colours`` (v, 3) uint8, ``part`` (v,) uint8,
    ``triangles`` (t, 3) uint32, ``wear_max_um`` (colour bar top [µm]), ``size_mm``,
    ``view_side`` (±1: the side of the first view).
    The inverse of the page's embedding (used to export the same data elsewhere
    and by the tests)."""
    text = Path(path).read_text(encoding="utf-8")
    head, sep, rest = text.partition("const DATA = ")
    if not sep:
        raise GeometryError(f"{path}: not a 3D view page (no DATA)")
    data, _ = json.JSONDecoder().raw_decode(rest)
    wmax = head.rsplit("<span>", 1)[-1].split("</span>", 1)[0]

    def dec(key, dtype, width):
        a = np.frombuffer(base64.b64decode(data[key]), dtype=dtype)
        return a.reshape(-1, width) if width > 1 else a

    return {"positions": dec("positions", np.float32, 3), "colours": dec("colours", np.uint8, 3),
            "part": dec("part", np.uint8, 1), "triangles": dec("triangles", np.uint32, 3),
            "wear_max_um": float(wmax), "size_mm": float(data["size_mm"]), "view_side": float(data["view_side"])}
