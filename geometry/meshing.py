"""Small gmsh helpers shared by the sector and the bar.

The gmsh API is a process-wide singleton: :func:`gmsh_session` initialises
it quietly, turns any gmsh exception into :class:`GeometryError` and always
finalises, so that it can be used again and again in one process (the
tests do). Everything else here works on the current model.
"""
from __future__ import annotations

import contextlib
import math
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from workflow.errors import GeometryError
from workflow.io import atomic_path

#: gmsh element types: 4-node and 10-node tetrahedra, 3- and 6-node triangles.
TET = {1: 4, 2: 11}
TRI = {1: 2, 2: 9}
#: Smallest acceptable tetrahedron quality (see :func:`tet_quality`): below
#: this an element is a near-flat sliver that spoils the stiffness matrix's
#: conditioning. Gmsh's Delaunay leaves ~1e-3…5e-2 next to the coarse
#: structured flanks (their cells fix the shape of the tetrahedra on them).
MIN_QUALITY = 5e-4
#: Tolerance for finding model entities by bounding box, relative to the
#: model size (OCC pads bounding boxes by its own tolerance, ~1e-7).
BBOX_TOL = 1e-5


@contextlib.contextmanager
def gmsh_session(name: str) -> Iterator[None]:
    """Initialise gmsh quietly with one empty model; finalise on exit.

    Any exception from gmsh becomes ``GeometryError("gmsh failed: …")``;
    our own :class:`~workflow.errors.BladewearError`\\ s pass through.
    """
    import gmsh

    # readConfigFiles=False: a user's gmshrc must not change our meshes.
    gmsh.initialize([], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        # One thread: gmsh's parallel meshers are not bit-reproducible.
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add(name)
        yield
    except Exception as exc:
        # gmsh raises bare ``Exception`` carrying its last error message;
        # anything else (ours, or a bug) keeps its own type.
        if type(exc) is Exception:
            raise GeometryError(f"gmsh failed: {exc}") from exc
        raise
    finally:
        gmsh.finalize()


def set_mesh_options(h_min: float, h_max: float) -> None:
    """Quality-oriented meshing options (element size bounds in m)."""
    import gmsh

    opt = gmsh.option.setNumber
    opt("Mesh.MeshSizeMin", h_min)
    opt("Mesh.MeshSizeMax", h_max)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 1)
    opt("Mesh.Algorithm", 6)        # Frontal-Delaunay 2D: well-shaped triangles
    opt("Mesh.Algorithm3D", 1)      # Delaunay 3D
    opt("Mesh.Optimize", 1)         # remove slivers
    opt("Mesh.SecondOrderIncomplete", 0)   # 10-node tetrahedra
    opt("Mesh.SecondOrderLinear", 0)       # mid-edge nodes on the curved geometry
    opt("Mesh.MshFileVersion", 4.1)
    opt("Mesh.Binary", 0)
    opt("Mesh.SaveAll", 0)          # only physical groups' elements


def add_group(dim: int, tags: list[int], tag: int, name: str) -> None:
    """Physical group with a fixed tag and name."""
    import gmsh

    gmsh.model.addPhysicalGroup(dim, list(tags), tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def boundary(dim_tags: list[tuple[int, int]], dim: int) -> list[int]:
    """Tags of the boundary entities of dimension ``dim`` of ``dim_tags``."""
    import gmsh

    out = list(dim_tags)
    while out and out[0][0] > dim:   # one dimension down at a time
        out = gmsh.model.getBoundary(out, combined=False, oriented=False, recursive=False)
    return sorted({abs(t) for (d, t) in out if d == dim})


def faces_of(volume: int) -> list[int]:
    """Surface tags bounding a volume."""
    import gmsh

    return sorted({abs(t) for (_, t) in gmsh.model.getBoundary([(3, volume)], combined=False,
                                                                 oriented=False)})


def faces_in_box(volume: int, lo, hi, tol: float) -> list[int]:
    """Faces of ``volume`` whose bounding box lies within [lo, hi] ± tol."""
    import gmsh

    inside = gmsh.model.getEntitiesInBoundingBox(lo[0] - tol, lo[1] - tol, lo[2] - tol,
                                                  hi[0] + tol, hi[1] + tol, hi[2] + tol, 2)
    own = set(faces_of(volume))
    return sorted(t for (_, t) in inside if t in own)


def one_face(volume: int, lo, hi, tol: float, what: str) -> int:
    """The single face of ``volume`` inside the box; GeometryError otherwise."""
    found = faces_in_box(volume, lo, hi, tol)
    if len(found) != 1:
        raise GeometryError(f"gmsh failed: expected one {what} face, found {len(found)} "
                            "(the CAD operations did not give the expected topology)")
    return found[0]


def make_structured(face: int, n_along: int, n_across: int, along_axis: int = 0, across_bump: float = 1.0) -> None:
    """Transfinite (structured) mesh of a 4-sided face: ``n_along`` vertices
    on the edges parallel to ``along_axis``, ``n_across`` on the others,
    evenly spaced or, with ``across_bump`` < 1, crowded towards both ends of
    the across edges (gmsh's symmetric "Bump": the same on either orientation
    of a curve, so two faces meshed alike stay node-to-node)."""
    import gmsh

    for c in boundary([(2, face)], 1):
        b = gmsh.model.getBoundingBox(1, c)
        ext = np.array(b[3:]) - np.array(b[:3])
        along = ext[along_axis] >= 0.5 * np.max(ext)
        if along or across_bump >= 1.0:
            gmsh.model.mesh.setTransfiniteCurve(c, n_along if along else n_across)
        else:
            gmsh.model.mesh.setTransfiniteCurve(c, n_across, "Bump", float(across_bump))
    gmsh.model.mesh.setTransfiniteSurface(face)


IDENTITY = [1.0, 0.0, 0.0, 0.0,
            0.0, 1.0, 0.0, 0.0,
            0.0, 0.0, 1.0, 0.0,
            0.0, 0.0, 0.0, 1.0]


def set_point_sizes(points: list[int], size_of: Callable[[np.ndarray], float]) -> None:
    """Mesh size at each geometric point from its coordinates."""
    import gmsh

    for pt in points:
        xyz = np.array(gmsh.model.getValue(0, pt, []))
        gmsh.model.mesh.setSize([(0, pt)], float(size_of(xyz)))


#: Largest growth of the element size per unit distance away from a refined zone
#: (dimensionless): gentle enough for Delaunay to grade without slivers.
GROWTH = 0.3


def refine_near(segments, h_near: float, h_far: float, zone: float) -> None:
    """Mesh size ``h_near`` [m] within ``zone`` [m] of the segments, growing beyond by
    :data:`GROWTH` m of size per m of distance up to ``h_far`` [m]; elsewhere the point sizes
    hold (gmsh takes the smallest size of every source).

    ``segments``: ((y0, z0), (y1, z1)) pairs [m] in the y–z plane, each the section of a face
    extruded along x (the dovetail's flanks). The distance is exact, in closed form: gmsh's
    Distance field would measure it to the faces' mesh nodes, as far apart as the contact grid.
    """
    import gmsh

    # gmsh's expression parser reads neither exponents nor a doubled sign: fixed-point, bracketed.
    num = lambda v: f"({float(v):.15f})"
    dist = []
    for (y0, z0), (y1, z1) in segments:
        dy, dz = y1 - y0, z1 - z0
        t = f"min(max(((y - {num(y0)})*{num(dy)} + (z - {num(z0)})*{num(dz)})/{num(dy * dy + dz * dz)}, 0), 1)"
        dist.append(f"sqrt((y - {num(y0)} - {t}*{num(dy)})^2 + (z - {num(z0)} - {t}*{num(dz)})^2)")
    d = dist[0]
    for other in dist[1:]:
        d = f"min({d}, {other})"
    fld = gmsh.model.mesh.field
    size = fld.add("MathEval")
    fld.setString(size, "F", f"min(max({num(h_near)} + {num(GROWTH)}*({d} - {num(zone)}), {num(h_near)}), "
                             f"{num(max(h_far, h_near))})")
    fld.setAsBackgroundMesh(size)


def generate(order: int, volumes: list[int]) -> None:
    """Mesh in 3D, raise the order, and check every volume got tetrahedra."""
    import gmsh

    gmsh.model.mesh.generate(3)
    if order > 1:
        gmsh.model.mesh.setOrder(order)
    for v in volumes:
        types, tags, _ = gmsh.model.mesh.getElements(3, v)
        if sum(len(t) for t in tags) == 0:
            raise GeometryError(f"gmsh failed: volume {v} was not meshed")


def tet_quality(order: int) -> tuple[float, float]:
    """(min, mean) quality of the straight-sided tetrahedra of the current
    mesh: η = 6√2·V / ℓ_rms³ (1 for a regular tetrahedron, → 0 for a sliver,
    < 0 if inverted)."""
    import gmsh

    ntags, xyz, _ = gmsh.model.mesh.getNodes()
    pos = np.empty((int(ntags.max()) + 1, 3))
    pos[ntags.astype(np.int64)] = xyz.reshape(-1, 3)
    _, conn = gmsh.model.mesh.getElementsByType(TET[order])
    conn = conn.astype(np.int64).reshape(-1, 4 if order == 1 else 10)[:, :4]
    p = pos[conn]
    e = [p[:, j] - p[:, i] for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))]
    vol = np.einsum("ij,ij->i", e[0], np.cross(e[1], e[2])) / 6.0
    lrms = np.sqrt(sum(np.einsum("ij,ij->i", v, v) for v in e) / 6.0)
    q = 6.0 * math.sqrt(2.0) * vol / lrms ** 3
    return float(q.min()), float(q.mean())


def min_jacobian_ratio(order: int) -> float:
    """min over elements of (min det J / max det J) at the nodes of each
    tetrahedron: > 0 means no curved element is folded."""
    import gmsh

    if order == 1:
        return 1.0
    ref = [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1,
           .5, 0, 0, .5, .5, 0, 0, .5, 0, 0, 0, .5, 0, .5, .5, .5, 0, .5]
    _, det, _ = gmsh.model.mesh.getJacobians(TET[order], ref)
    det = np.asarray(det).reshape(-1, 10)
    # Orientation of a tetrahedron is arbitrary; what matters is one sign.
    ratio = det.min(axis=1) / det.max(axis=1)
    flip = det.max(axis=1) < 0
    ratio[flip] = det[flip].max(axis=1) / det[flip].min(axis=1)
    return float(ratio.min())


def check_quality(order: int) -> dict:
    """Quality figures of the current mesh; GeometryError if unusable."""
    qmin, qmean = tet_quality(order)
    jac = min_jacobian_ratio(order)
    if qmin < MIN_QUALITY or jac <= 0.0:
        raise GeometryError(f"gmsh failed: mesh quality too poor (min tetrahedron quality {qmin:.3g}, "
                            f"min Jacobian ratio {jac:.3g}); change the mesh sizes")
    return {"quality_min": qmin, "quality_mean": qmean, "jacobian_ratio_min": jac}


def write_msh(msh_path, measure: Callable[[Path], dict] | None = None) -> dict:
    """Write the current mesh to ``msh_path`` (gmsh 4.1) atomically.

    ``measure(tmp)`` runs on the written temporary file before it replaces
    ``msh_path``, so a mesh that fails its checks never lands.
    """
    import gmsh

    with atomic_path(msh_path, suffix=".msh") as tmp:
        gmsh.write(str(tmp))
        _sort_periodic_section(tmp)
        return measure(tmp) if measure is not None else {}


def _sort_periodic_section(path: Path) -> None:
    """Sort the node pairs of each link in a 4.1 ``$Periodic`` section.

    gmsh writes them in hash-map order, which changes from run to run; sorted,
    the same parameters give a byte-identical file (cache keys can hash it).
    """
    lines = Path(path).read_text().split("\n")
    try:
        i = lines.index("$Periodic") + 1
    except ValueError:
        return
    n_links = int(lines[i])
    i += 1
    for _ in range(n_links):
        i += 2                                   # entity line, affine line
        n = int(lines[i])
        i += 1
        block = sorted(lines[i:i + n], key=lambda ln: tuple(int(v) for v in ln.split()))
        lines[i:i + n] = block
        i += n
    if lines[i] != "$EndPeriodic":
        raise GeometryError(f"gmsh failed: unexpected $Periodic layout in {path}")
    Path(path).write_text("\n".join(lines))


@contextlib.contextmanager
def reading(msh_path) -> Iterator[str]:
    """Load a .msh into a fresh model of the *current* session; remove it
    afterwards and restore the previous current model."""
    import gmsh

    previous = gmsh.model.getCurrent()
    gmsh.model.add("readback")
    try:
        gmsh.merge(str(msh_path))
        yield "readback"
    finally:
        gmsh.model.setCurrent("readback")
        gmsh.model.remove()
        gmsh.model.setCurrent(previous)


def group_nodes(dim: int, group: int) -> tuple[np.ndarray, np.ndarray]:
    """Node tags of a physical group's elements in the current model:
    (corner/vertex nodes, all nodes incl. high-order ones), unique, sorted."""
    import gmsh

    corners, every = [], []
    for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, group):
        types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
        for t, n in zip(types, nodes):
            _, _, _, nn, _, nprim = gmsh.model.mesh.getElementProperties(t)
            n = np.asarray(n, dtype=np.int64).reshape(-1, nn)
            corners.append(n[:, :nprim].ravel())
            every.append(n.ravel())
    cat = lambda a: np.unique(np.concatenate(a)) if a else np.zeros(0, dtype=np.int64)
    return cat(corners), cat(every)


def node_coords(tags: np.ndarray) -> np.ndarray:
    """Coordinates (n, 3) of the given node tags in the current model."""
    import gmsh

    all_tags, xyz, _ = gmsh.model.mesh.getNodes()
    lookup = dict(zip(all_tags.astype(np.int64).tolist(), range(len(all_tags))))
    xyz = xyz.reshape(-1, 3)
    return xyz[[lookup[int(t)] for t in tags]] if len(tags) else np.zeros((0, 3))


def mesh_counts() -> tuple[int, int]:
    """(number of nodes, number of volume elements) of the current model."""
    import gmsh

    ntags, _, _ = gmsh.model.mesh.getNodes()
    nel = 0
    for _, tags in zip(*gmsh.model.mesh.getElements(3)[:2]):
        nel += len(tags)
    return int(len(ntags)), int(nel)
