"""Wear back onto the geometry: wear field, worn mesh, and their files.

Input: the nodal wear depth of every contact pair, split into the blade's and
the disk's share (``W_blade + W_disk = W``), and the pairs' positions, unit
normals n (from the disk into the blade, contracts §2) and flank ids.

1. **Wear field.** On each body's flank (facet groups 11/12 blade, 21/22
   disk; contracts §1) the share is interpolated from the contact nodes to
   every geometry node of the flank (:mod:`geometry.flankmap`: exact at the
   contact nodes, linear in the flank plane between them). As a dolfinx
   Function it is a scalar Lagrange field of the geometry's degree, zero off
   the flanks.
2. **Flank motion.** Material is removed, so each flank surface moves into
   its own body: the blade flank by ``+W_blade n`` (n points into the blade),
   the disk flank by ``−W_disk n``. The gap ``g = u_N + gap + W`` of
   contracts §6 opens by exactly W.
3. **Extension into the bodies.** A mesh-motion problem carries the flank
   motion smoothly inside: per component Laplace ("harmonic") or linear
   elasticity stiffened in small cells ("elastic"), Dirichlet data = the
   flank motion on the flanks and zero on every other boundary facet (the
   rest of the surface is not worn and keeps its shape). Blade and disk are
   separate volumes in one mesh, so the problem decouples per body.
4. **Checks.** Before solving, the motion of every flank node is compared
   with the local element size (smallest height of the tetrahedra at the
   node, :func:`geometry.jacobians.node_sizes`); above ``max_fraction`` the
   remap is refused with a :class:`GeometryError` naming the pair, body and
   fraction. After solving, the signed Jacobian determinants of every cell
   at its vertices and quadrature points must keep their sign.

Zero wear returns the coordinates unchanged, bit for bit (nothing is solved).
Everything is SI (m); the mesh is serial (one rank), like the rest of the
FE half's post-processing.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from geometry.flankmap import interpolate_on_flank
from geometry.jacobians import jacobian_determinants, node_sizes, orientation_ratio
from workflow.errors import GeometryError

#: Facet group of each (body, flank) — contracts §1; flank 0 intrados, 1 extrados.
FLANK_GROUPS = {("blade", 0): 11, ("blade", 1): 12, ("disk", 0): 21, ("disk", 1): 22}
#: Direction of the motion along n (disk → blade) that takes each body's flank into its own body.
BODY_SIGN = {"blade": 1.0, "disk": -1.0}
FLANK_NAMES = ("intrados", "extrados")
SMOOTHING = ("harmonic", "elastic")
#: Orientation ratio det_after/det_before below which a cell counts as (nearly) inverted.
MIN_ORIENTATION_RATIO = 0.0


@dataclass
class PairWear:
    """Wear per contact pair (p pairs), SI.

    ``position`` (p, 3) [m], ``normal`` (p, 3) unit, from the disk into the
    blade; ``flank`` (p,) 0 intrados / 1 extrados; ``w_blade``, ``w_disk``
    (p,) [m] ≥ 0, the shares of the wear depth removed from each body.
    """

    position: np.ndarray
    normal: np.ndarray
    flank: np.ndarray
    w_blade: np.ndarray
    w_disk: np.ndarray

    @classmethod
    def from_total(cls, position, normal, flank, W, blade_share: float) -> "PairWear":
        """Split a total wear depth W (p,) [m]: ``blade_share``·W on the blade, the rest on the disk."""
        w_blade, w_disk = wear_shares(W, blade_share)
        return cls(np.asarray(position, float), np.asarray(normal, float), np.asarray(flank), w_blade, w_disk)

    def share(self, body: str) -> np.ndarray:
        return self.w_blade if body == "blade" else self.w_disk


def wear_shares(W: np.ndarray, blade_share: float) -> tuple[np.ndarray, np.ndarray]:
    """``(W_blade, W_disk)`` [m] with ``W_blade = s·W`` and ``W_disk = W − W_blade``."""
    W = np.asarray(W, dtype=float)
    if not 0.0 <= blade_share <= 1.0:
        raise GeometryError(f"remap: blade_share = {blade_share} must lie in [0, 1]")
    if np.any(W < 0) or not np.all(np.isfinite(W)):
        raise GeometryError("remap: wear depths must be finite and ≥ 0")
    w_blade = blade_share * W
    return w_blade, W - w_blade


def pair_wear(contact, table: dict, blade_share: float) -> PairWear:
    """:class:`PairWear` in bundle pair order from the wear stage's table
    (:func:`workflow.report.wear.read_wear_csv`) and the bundle's ``contact``.

    Rows are matched by ``pair`` index and checked against the bundle's pair
    positions (1 µm); shares come from the CSV when present, else from
    ``blade_share``.
    """
    from workflow.errors import BundleError

    p = contact.n_pairs
    if contact.position is None or contact.flank is None:
        raise BundleError("the bundle's contact.npz lacks position/flank, needed to map wear onto the mesh")
    idx = table["pair"]
    if len(idx) != p or set(idx.tolist()) != set(range(p)):
        raise GeometryError(f"wear.csv has {len(idx)} rows / pairs {idx.min()}..{idx.max()}, "
                            f"the bundle {p} pairs")
    order = np.argsort(idx)
    if table["position"] is not None:
        off = np.linalg.norm(table["position"][order] - contact.position, axis=1).max()
        if off > 1e-6:
            raise GeometryError(f"wear.csv positions differ from the bundle's pairs by up to {off:.3g} m "
                                f"(was the wear computed on another bundle?)")
    W = table["W"][order]
    if table["W_blade"] is not None and table["W_disk"] is not None:
        w_blade, w_disk = table["W_blade"][order], table["W_disk"][order]
    else:
        w_blade, w_disk = wear_shares(W, blade_share)
    return PairWear(np.asarray(contact.position, float), np.asarray(contact.normal, float),
                    np.asarray(contact.flank), np.clip(w_blade, 0.0, None), np.clip(w_disk, 0.0, None))


@dataclass
class FlankNodes:
    """Geometry nodes of one flank facet group: ``nodes`` (k,) indices, ``tag``."""

    body: str
    flank: int
    tag: int
    nodes: np.ndarray


@dataclass
class Remap:
    """Result of :func:`remap_wear` (arrays over the N geometry nodes, SI).

    ``x0``: (N, 3) original coordinates [m]; ``motion``: (N, 3) node motion
    [m]; ``wear``: (N,) the body's wear share at flank nodes, 0 elsewhere [m];
    ``flanks``: the flank node sets; ``max_fraction``: largest flank motion /
    local element size; ``orientation``: smallest det ratio over all cells and
    check points (1 for no motion); ``worst_pair``: pair index of the largest
    fraction (−1 without wear).
    """

    x0: np.ndarray
    motion: np.ndarray
    wear: np.ndarray
    flanks: list[FlankNodes]
    max_fraction: float = 0.0
    orientation: float = 1.0
    worst_pair: int = -1
    info: dict = field(default_factory=dict)

    @property
    def x(self) -> np.ndarray:
        """(N, 3) worn coordinates [m]; the very same values as ``x0`` without wear."""
        if not np.any(self.motion):
            return self.x0.copy()
        return self.x0 + self.motion

    @property
    def max_node_motion(self) -> float:
        """Largest node displacement [m] (equals the largest wear share)."""
        return float(np.linalg.norm(self.motion, axis=1).max()) if len(self.motion) else 0.0


# ----------------------------------------------------------- the steps, on arrays

def flank_node_sets(mesh, facet_tags) -> list[FlankNodes]:
    """The geometry nodes (vertices and mid-edge nodes) of each flank group present."""
    from reduction import dolfinx_compat as dc

    V = dc.vector_space(mesh, dc.geometry_degree(mesh))
    node_of_block = _node_of_block(V)
    out = []
    for (body, flank), tag in FLANK_GROUPS.items():
        facets = dc.tagged_entities(facet_tags, tag)
        if facets.size == 0:
            continue
        out.append(FlankNodes(body, flank, tag, np.sort(node_of_block[dc.blocks_of_facets(V, facets)])))
    return out


def flank_field(x: np.ndarray, flanks: list[FlankNodes], pairs: PairWear) -> tuple[np.ndarray, np.ndarray]:
    """Wear share (N,) [m] and prescribed motion (N, 3) [m] at the flank nodes.

    Each flank node takes the share of its own body, interpolated from the
    pairs of its flank; the motion is along that body's inward normal (the
    pair normals, interpolated and renormalised). Zero off the flanks.
    """
    wear = np.zeros(len(x))
    motion = np.zeros((len(x), 3))
    for fs in flanks:
        sel = np.flatnonzero(np.asarray(pairs.flank) == fs.flank)
        if sel.size == 0:
            raise GeometryError(f"remap: facet group {fs.tag} ({fs.body} {FLANK_NAMES[fs.flank]}) has no "
                                f"contact pairs with flank = {fs.flank}")
        share = pairs.share(fs.body)[sel]
        vals = interpolate_on_flank(pairs.position[sel], np.column_stack([share, pairs.normal[sel]]), x[fs.nodes])
        n = vals[:, 1:] / np.linalg.norm(vals[:, 1:], axis=1, keepdims=True)
        wear[fs.nodes] = vals[:, 0]
        motion[fs.nodes] = BODY_SIGN[fs.body] * vals[:, :1] * n
    return wear, motion


def check_fraction(x: np.ndarray, cells: np.ndarray, motion: np.ndarray, flanks: list[FlankNodes],
                   pairs: PairWear, max_fraction: float) -> tuple[float, int]:
    """Largest (flank-node motion / local element size) and the pair nearest to it.

    Raises :class:`GeometryError` naming the pair, body, flank and fraction
    when it exceeds ``max_fraction``.
    """
    h = node_sizes(x, cells)
    nodes = np.concatenate([fs.nodes for fs in flanks]) if flanks else np.zeros(0, int)
    if nodes.size == 0:
        return 0.0, -1
    frac = np.linalg.norm(motion[nodes], axis=1) / h[nodes]
    i = int(np.argmax(frac))
    worst = float(frac[i])
    node = nodes[i]
    pair = int(np.argmin(np.linalg.norm(pairs.position - x[node], axis=1)))
    if not np.any(motion[nodes]):
        return 0.0, -1
    if worst > max_fraction:
        body = next(fs for fs in flanks if node in fs.nodes)
        raise GeometryError(
            f"remap: wear of pair {pair} ({body.body} flank {FLANK_NAMES[body.flank]}, group {body.tag}) moves "
            f"its node by {np.linalg.norm(motion[node]):.3g} m = {worst:.3g} × the local element size "
            f"{h[node]:.3g} m, above remap.max_fraction = {max_fraction:g}; refine the flank mesh or "
            f"raise remap.max_fraction")
    return worst, pair


def extend_motion(mesh, flank_motion: np.ndarray, smoothing: str = "harmonic") -> np.ndarray:
    """Node motion (N, 3) [m] inside the bodies from the motion prescribed at the
    flank nodes (zero on the rest of the boundary), by a mesh-motion solve.

    ``harmonic``: −Δu = 0 per component. ``elastic``: linear elasticity
    (λ = μ, Poisson 0.25) with the stiffness scaled by 1/cell volume so small
    cells deform less. Dirichlet DOFs: every boundary facet's nodes.
    """
    import ufl

    from reduction import dolfinx_compat as dc

    if smoothing not in SMOOTHING:
        raise GeometryError(f"remap.smoothing = {smoothing!r} is not one of: {', '.join(SMOOTHING)}")
    V = dc.vector_space(mesh, dc.geometry_degree(mesh))
    node_of_block = _node_of_block(V)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    if smoothing == "harmonic":
        a = ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx
    else:
        eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
        sigma = 2.0 * eps(u) + ufl.tr(eps(u)) * ufl.Identity(3)
        # ufl.CellVolume is affine-only in 0.5.2: the volumes come from the vertices.
        cells = dc.cell_geometry_nodes(mesh)
        vol = np.abs(jacobian_determinants(mesh.geometry.x, cells[:, :4]).mean(axis=1)) / 6.0
        a = ufl.inner(sigma, eps(v)) * dc.cellwise_function(mesh, vol.min() / vol) * ufl.dx
    zero = dolfinx_constant(mesh, (0.0, 0.0, 0.0))
    L = ufl.inner(zero, v) * ufl.dx
    blocks = dc.blocks_of_facets(V, dc.exterior_facets(mesh))
    sol = dc.solve_with_dirichlet(a, L, V, blocks, flank_motion[node_of_block[blocks]])
    out = np.asarray(sol.x.array).reshape(-1, 3)[dc.geometry_node_blocks(V)]
    # The flank values are the prescribed ones exactly (not via the solver's round-off).
    bnodes = node_of_block[blocks]
    out[bnodes] = flank_motion[bnodes]
    return out


def dolfinx_constant(mesh, value):
    from dolfinx import fem
    from petsc4py import PETSc

    return fem.Constant(mesh, PETSc.ScalarType(value))


def _node_of_block(V) -> np.ndarray:
    """Inverse of ``geometry_node_blocks``: the geometry node of each block of V."""
    from reduction import dolfinx_compat as dc

    blocks = dc.geometry_node_blocks(V)
    out = np.full(blocks.max() + 1, -1, dtype=np.int64)
    out[blocks] = np.arange(len(blocks))
    return out


@dataclass
class FlankSurface:
    """One flank as plain arrays for figures: ``points`` (k, 3) [m] (the flank's
    geometry nodes), ``triangles`` (t, 3) linear triangles over them (each
    quadratic facet split in four), ``wear`` (k,) [m], ``normal`` (3,) the
    mean unit normal from the disk into the blade; ``contact`` (q, 3) the
    contact node positions [m]."""

    body: str
    flank: int
    tag: int
    points: np.ndarray
    triangles: np.ndarray
    wear: np.ndarray
    normal: np.ndarray
    contact: np.ndarray

    @property
    def label(self) -> str:
        return f"{self.body} flank, {FLANK_NAMES[self.flank]} (group {self.tag})"


def split_quadratic_triangles(x: np.ndarray, vertex_tris: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Linear triangles (4t, 3) covering quadratic triangles given by their vertex
    nodes (t, 3); the mid-edge node of each edge is the node of ``nodes`` nearest
    to the edge's midpoint (for straight-sided or linear facets, the corner
    triangles are returned whole when no mid node lies there)."""
    from scipy.spatial import cKDTree

    vertex_tris = np.asarray(vertex_tris, dtype=np.int64)
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(vertex_tris) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    a, b, c = vertex_tris.T
    tree = cKDTree(x[nodes])
    mids = []
    for p, q in ((a, b), (b, c), (c, a)):
        d, i = tree.query(0.5 * (x[p] + x[q]))
        edge = np.linalg.norm(x[p] - x[q], axis=1)
        m = nodes[i]
        m[d > 0.25 * edge] = -1  # no mid node on this edge (linear facet)
        mids.append(m)
    ab, bc, ca = mids
    if np.any(ab < 0):
        return vertex_tris
    return np.concatenate([np.column_stack(t) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])


def flank_surfaces(mesh, facet_tags, remap: Remap, pairs: PairWear, worn: bool = False) -> list[FlankSurface]:
    """Every flank group as a :class:`FlankSurface` (on the worn coordinates if ``worn``)."""
    from reduction import dolfinx_compat as dc

    x = remap.x if worn else remap.x0
    out = []
    for fs in remap.flanks:
        facets = dc.tagged_entities(facet_tags, fs.tag)
        tris = split_quadratic_triangles(x, dc.facet_vertex_nodes(mesh, facets), fs.nodes)
        local = np.full(len(x), -1, dtype=np.int64)
        local[fs.nodes] = np.arange(len(fs.nodes))
        sel = np.asarray(pairs.flank) == fs.flank
        n = pairs.normal[sel].mean(axis=0)
        out.append(FlankSurface(fs.body, fs.flank, fs.tag, x[fs.nodes], local[tris], remap.wear[fs.nodes],
                                n / np.linalg.norm(n), pairs.position[sel]))
    return out


# ------------------------------------------------------------------ the whole trip

def remap_wear(mesh, facet_tags, pairs: PairWear, max_fraction: float = 0.3,
               smoothing: str = "harmonic") -> Remap:
    """Wear field and worn node coordinates for ``mesh`` (not modified).

    Raises :class:`GeometryError` if a flank node would move by more than
    ``max_fraction`` × its local element size, or if any cell would invert.
    """
    from reduction import dolfinx_compat as dc

    if mesh.comm.size > 1:
        raise GeometryError("remap runs on one process (the mesh is post-processed serially)")
    x0 = np.array(mesh.geometry.x[:, :3], dtype=float)  # a copy: the mesh stays as it is
    cells = dc.cell_geometry_nodes(mesh)
    flanks = flank_node_sets(mesh, facet_tags)
    if not flanks:
        raise GeometryError("remap: the mesh has no flank facet groups (11, 12, 21, 22; contracts §1)")
    wear, flank_motion = flank_field(x0, flanks, pairs)
    if not np.any(flank_motion):
        return Remap(x0, np.zeros_like(x0), wear, flanks, info={"smoothing": smoothing, "solved": False})
    frac, pair = check_fraction(x0, cells, flank_motion, flanks, pairs, max_fraction)
    motion = extend_motion(mesh, flank_motion, smoothing)
    ratio = orientation_ratio(jacobian_determinants(x0, cells), jacobian_determinants(x0 + motion, cells))
    worst = float(ratio.min())
    if worst <= MIN_ORIENTATION_RATIO:
        raise GeometryError(f"remap: the worn mesh would invert {int(np.sum(ratio <= 0))} cell(s) "
                            f"(smallest det ratio {worst:.3g}) although the flank motion is only "
                            f"{frac:.3g} × the local element size; lower remap.max_fraction or refine the mesh")
    return Remap(x0, motion, wear, flanks, max_fraction=frac, orientation=worst, worst_pair=pair,
                 info={"smoothing": smoothing, "solved": True})


def wear_functions(mesh, remap: Remap):
    """dolfinx Functions of the geometry's degree: ``wear_depth`` (scalar, m) and
    ``wear_motion`` (vector, m), for XDMF output."""
    from reduction import dolfinx_compat as dc

    k = dc.geometry_degree(mesh)
    S, V = dc.scalar_space(mesh, k), dc.vector_space(mesh, k)
    w, d = dc.function(S, "wear_depth"), dc.function(V, "wear_motion")
    w.x.array[dc.geometry_node_blocks(S)] = remap.wear
    d.x.array.reshape(-1, 3)[dc.geometry_node_blocks(V)] = remap.motion
    return w, d


def write_wear_xdmf(path: str | Path, mesh, remap: Remap, cell_tags=None, facet_tags=None) -> Path:
    """The original mesh with the wear depth and motion fields → ``path`` (.xdmf + .h5)."""
    from reduction import dolfinx_compat as dc

    return _atomic_xdmf(path, lambda p: dc.write_functions_xdmf(p, mesh, wear_functions(mesh, remap),
                                                                 cell_tags, facet_tags))


def write_worn_xdmf(path: str | Path, mesh, remap: Remap, cell_tags=None, facet_tags=None) -> Path:
    """The worn mesh (with tags and the wear depth on it) → ``path``; ``mesh`` is
    moved to the worn coordinates only while writing."""
    from reduction import dolfinx_compat as dc

    with dc.moved(mesh, remap.x):
        w, _ = wear_functions(mesh, remap)
        return _atomic_xdmf(path, lambda p: dc.write_functions_xdmf(p, mesh, [w], cell_tags, facet_tags))


def write_worn_nodes(path: str | Path, mesh, remap: Remap) -> Path:
    """``.npz`` with ``coords`` (worn, N×3, m), ``coords_new``, ``motion`` and
    ``gmsh_node_tags`` (each geometry node's gmsh tag, for writing a worn ``.msh``)."""
    from reduction import dolfinx_compat as dc
    from workflow.io import write_npz

    tags = dc.input_global_indices(mesh) + 1  # gmshio numbers input nodes by tag − 1
    order = np.argsort(tags)
    return write_npz(path, coords=remap.x[order], coords_new=remap.x0[order], motion=remap.motion[order],
                     gmsh_node_tags=tags[order])


def write_worn_msh(msh_in: str | Path, msh_out: str | Path, node_tags: np.ndarray, coords: np.ndarray) -> Path:
    """Copy the gmsh file ``msh_in`` to ``msh_out`` with the nodes ``node_tags``
    moved to ``coords`` (N, 3) [m] — the worn mesh for a re-run of the assembly."""
    import gmsh

    from workflow.io import atomic_path

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.merge(str(msh_in))
        for tag, xyz in zip(np.asarray(node_tags, dtype=int), np.asarray(coords, dtype=float)):
            gmsh.model.mesh.setNode(int(tag), xyz.tolist(), [])
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        with atomic_path(msh_out, suffix=".msh") as tmp:
            gmsh.write(str(tmp))
    finally:
        gmsh.finalize()
    return Path(msh_out)


def _atomic_xdmf(path: str | Path, write) -> Path:
    """Write an .xdmf/.h5 pair through a temporary folder, then move both in place
    (the .xdmf names its .h5 by file name, so the pair must keep its stem)."""
    import shutil
    import tempfile

    from workflow.io import write_error

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent))
    try:
        write(tmp / path.name)
        h5 = path.with_suffix(".h5")
        (tmp / h5.name).replace(h5)  # data first, then the file that points at it
        (tmp / path.name).replace(path)
    except OSError as exc:
        raise write_error(path, exc) from exc
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path
