"""Every call that depends on the dolfinx version (here Debian's 0.5.2) lives here.

A newer dolfinx should be a one-file change (DESIGN §4). The rest of
``reduction`` only sees: a mesh with cell and facet tags, function spaces,
UFL forms turned into scipy/numpy objects on rank 0 in *global* DOF numbering,
and DOF lookups (local block indices, their coordinates and global numbers).

Conventions used throughout:

* "block" = a node of a vector space (bs = 3 DOFs); DOF = bs·block + c.
* "local" indices are on this rank (owned first, then ghosts); "global"
  indices are dolfinx's global numbering, which is the numbering of the
  gathered scipy matrices.
* Gathers go to rank 0 (``ROOT``); other ranks get ``None``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem.petsc  # noqa: F401  (registers fem.petsc)
import dolfinx.io
import dolfinx.io.gmshio
from dolfinx import fem

from workflow.errors import GeometryError

ROOT = 0
VERSION = dolfinx.__version__


# ---------------------------------------------------------------- mesh input

def read_msh(path: str | Path, comm=MPI.COMM_WORLD, gdim: int = 3):
    """Read a gmsh ``.msh`` into ``(mesh, cell_tags, facet_tags)``.

    Rank ``ROOT`` reads the file and dolfinx distributes the mesh. Tags are
    the physical-group tags (contracts §1). Written against 0.5.2, whose own
    ``gmshio.read_from_msh`` is broken (it returns an unbound name), so this
    merges the file into a gmsh model and calls ``model_to_mesh``.
    """
    import gmsh

    path = Path(path)
    if not path.is_file():  # checked on every rank (shared file system) so none waits alone
        raise GeometryError(f"mesh file {path} does not exist")
    # gmsh 4.8 has no isInitialized(): this function owns a whole gmsh session,
    # so call it outside any other (use model_to_mesh inside one).
    if comm.rank == ROOT:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == ROOT:
            try:
                gmsh.merge(str(path))
            except Exception as exc:
                raise GeometryError(f"mesh file {path} cannot be read by gmsh: {exc}") from exc
            if not gmsh.model.getPhysicalGroups(3):
                raise GeometryError(f"mesh file {path} has no 3-D physical groups (contracts §1)")
        mesh, ct, ft = model_to_mesh(gmsh.model if comm.rank == ROOT else None, comm, gdim)
    finally:
        if comm.rank == ROOT:
            gmsh.finalize()
    return mesh, ct, ft


def model_to_mesh(model, comm=MPI.COMM_WORLD, gdim: int = 3):
    """A gmsh model (live on rank ``ROOT``) → ``(mesh, cell_tags, facet_tags)``."""
    import gmsh

    mesh, ct, ft = dolfinx.io.gmshio.model_to_mesh(model if model is not None else gmsh.model, comm, ROOT,
                                                   gdim=gdim)
    ct.name, ft.name = "cell_tags", "facet_tags"
    return mesh, ct, ft


def tag_values(tags) -> np.ndarray:
    """Distinct tag values present on any rank."""
    local = np.unique(tags.values)
    comm = tags.mesh.comm
    return np.unique(np.concatenate(comm.allgather(local)))


def tagged_entities(tags, values) -> np.ndarray:
    """Local entity indices whose tag is in ``values``."""
    return tags.indices[np.isin(tags.values, np.atleast_1d(values))]


def geometry_degree(mesh) -> int:
    """Polynomial degree of the coordinate element (2 for curved P2 tets)."""
    return int(mesh.geometry.cmap.degree)


def input_global_indices(mesh) -> np.ndarray:
    """For each local geometry node, its 0-based index in the input (gmsh) node list."""
    return np.asarray(mesh.geometry.input_global_indices, dtype=np.int64)


# ----------------------------------------------------------- spaces, measures

def vector_space(mesh, degree: int = 2):
    """Vector Lagrange space (bs = gdim)."""
    return fem.VectorFunctionSpace(mesh, ("Lagrange", degree))


def scalar_space(mesh, degree: int = 1):
    """Scalar Lagrange space."""
    return fem.FunctionSpace(mesh, ("Lagrange", degree))


def measures(mesh, cell_tags=None, facet_tags=None):
    """``(dx, ds)`` carrying the tags, so ``ds(11)`` integrates over group 11."""
    dx = ufl.Measure("dx", domain=mesh, subdomain_data=cell_tags)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
    return dx, ds


def constant(mesh, value):
    """A dolfinx Constant (scalar or array)."""
    return fem.Constant(mesh, PETSc.ScalarType(value) if np.isscalar(value) else np.asarray(value, dtype=float))


def function(V, name: str = "u"):
    """A zero-initialised finite-element function on ``V``."""
    f = fem.Function(V)
    f.name = name
    return f


# ------------------------------------------------------------ DOF book-keeping

def block_size(V) -> int:
    return int(V.dofmap.index_map_bs)


def n_owned_blocks(V) -> int:
    return int(V.dofmap.index_map.size_local)


def n_global_blocks(V) -> int:
    return int(V.dofmap.index_map.size_global)


def local_to_global_blocks(V, local: np.ndarray) -> np.ndarray:
    """Global block numbers of local (owned or ghost) block indices."""
    local = np.asarray(local, dtype=np.int32)
    return np.asarray(V.dofmap.index_map.local_to_global(local), dtype=np.int64)


def owned(V, local: np.ndarray) -> np.ndarray:
    """The owned subset of local block indices (each block counted on one rank)."""
    local = np.asarray(local)
    return local[local < n_owned_blocks(V)]


def block_coordinates(V) -> np.ndarray:
    """(n_local_blocks, 3) coordinates of each local DOF block [m]."""
    return np.asarray(V.tabulate_dof_coordinates(), dtype=float)


def blocks_on_facets(V, facet_tags, values) -> np.ndarray:
    """Local block indices of every DOF on the facets tagged ``values``.

    (For a vector space dolfinx returns block indices: DOF = bs·block + c.)
    """
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, mesh.topology.dim)
    return np.asarray(fem.locate_dofs_topological(V, fdim, tagged_entities(facet_tags, values)), dtype=np.int64)


def blocks_at_vertices_of_facets(V, facet_tags, values) -> np.ndarray:
    """Local block indices at the mesh *vertices* (not mid-edge nodes) of tagged facets."""
    mesh = V.mesh
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, 0)
    mesh.topology.create_connectivity(0, tdim)
    f2v = mesh.topology.connectivity(tdim - 1, 0)
    facets = tagged_entities(facet_tags, values)
    verts = np.unique(np.concatenate([f2v.links(f) for f in facets])) if facets.size else np.zeros(0, np.int32)
    return np.asarray(fem.locate_dofs_topological(V, 0, verts.astype(np.int32)), dtype=np.int64)


def gather_owned_blocks(V, local_blocks: np.ndarray, *arrays):
    """Gather owned entries to ``ROOT``: ``(global_blocks, *arrays_rows)``; None elsewhere.

    ``arrays`` are indexed by local block, i.e. ``a[local_blocks]`` is sent.
    """
    comm = V.mesh.comm
    mine = owned(V, local_blocks)
    parts = [local_to_global_blocks(V, mine)] + [np.asarray(a)[mine] for a in arrays]
    gathered = comm.gather(parts, root=ROOT)
    if comm.rank != ROOT:
        return None
    return tuple(np.concatenate([g[i] for g in gathered]) for i in range(len(parts)))


def gather_block_coordinates(V) -> np.ndarray | None:
    """(n_global_blocks, 3) coordinates of every DOF block, in global order, on ``ROOT``."""
    n_own = n_owned_blocks(V)
    out = gather_owned_blocks(V, np.arange(n_own), block_coordinates(V)[:n_own])
    if out is None:
        return None
    glob, xyz = out
    coords = np.empty((n_global_blocks(V), 3))
    coords[glob] = xyz
    return coords


# ---------------------------------------------------------------- assembly

def form(expr):
    """Compile a UFL form (dolfinx JIT, cached under ~/.cache/fenics); compiled forms pass through.

    Compile once and re-assemble when only coefficient values change (e.g. the
    prestress iterations): form processing costs ~0.1–1 s even with a warm cache.
    """
    return expr if isinstance(expr, fem.FormMetaClass) else fem.form(expr)


def assemble_matrix_scipy(a) -> sp.csr_matrix | None:
    """Assemble the bilinear form ``a`` (no BCs) → global scipy CSR on ``ROOT``."""
    A = dolfinx.fem.petsc.assemble_matrix(form(a))
    A.assemble()
    out = petsc_to_scipy(A)
    A.destroy()
    return out


def petsc_to_scipy(A: PETSc.Mat) -> sp.csr_matrix | None:
    """Gather a distributed PETSc AIJ matrix (global numbering) to scipy CSR on ``ROOT``."""
    comm = A.getComm().tompi4py()
    r0, r1 = A.getOwnershipRange()
    indptr, indices, data = A.getValuesCSR()
    local = sp.csr_matrix((data, indices, indptr), shape=(r1 - r0, A.getSize()[1]))
    parts = comm.gather((r0, local), root=ROOT)
    if comm.rank != ROOT:
        return None
    parts.sort(key=lambda t: t[0])
    return sp.vstack([p[1] for p in parts], format="csr")


def assemble_vector_numpy(L) -> np.ndarray | None:
    """Assemble the linear form ``L`` → global numpy vector on ``ROOT`` (ghosts summed)."""
    b = dolfinx.fem.petsc.assemble_vector(form(L))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = petsc_vec_to_numpy(b)
    b.destroy()
    return out


def assemble_vector_local(L) -> np.ndarray:
    """Assemble ``L``; return this rank's owned+ghost values (ghosts updated)."""
    b = dolfinx.fem.petsc.assemble_vector(form(L))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with b.localForm() as loc:
        out = loc.getArray().copy()
    b.destroy()
    return out


def assemble_scalar(J) -> float:
    """A functional summed over all ranks."""
    f = form(J)
    comm = f.mesh.comm if hasattr(f, "mesh") else MPI.COMM_WORLD
    return comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM)


def petsc_vec_to_numpy(v: PETSc.Vec) -> np.ndarray | None:
    """Owned parts of a distributed Vec, concatenated in global order on ``ROOT``."""
    comm = v.getComm().tompi4py()
    r0, _ = v.getOwnershipRange()
    parts = comm.gather((r0, v.getArray().copy()), root=ROOT)
    if comm.rank != ROOT:
        return None
    parts.sort(key=lambda t: t[0])
    return np.concatenate([p[1] for p in parts])


def set_function_from_global(u, values) -> None:
    """Fill ``u`` from a global DOF vector held on ``ROOT`` (broadcast, then each rank
    takes its owned and ghost entries)."""
    V = u.function_space
    comm = V.mesh.comm
    values = comm.bcast(values if comm.rank == ROOT else None, root=ROOT)
    bs = block_size(V)
    im = V.dofmap.index_map
    n_local = im.size_local + im.num_ghosts
    glob = local_to_global_blocks(V, np.arange(n_local))
    dofs = (bs * glob[:, None] + np.arange(bs)).ravel()
    u.x.array[: dofs.size] = np.asarray(values)[dofs]


# --------------------------------------------------------------- XDMF output

def write_mesh_xdmf(mesh, cell_tags, facet_tags, path: str | Path) -> Path:
    """Mesh plus cell and facet tags to ``path`` (.xdmf + .h5 beside it)."""
    path = Path(path)
    mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
    with dolfinx.io.XDMFFile(mesh.comm, str(path), "w") as xdmf:
        xdmf.write_mesh(mesh)
        if cell_tags is not None:
            xdmf.write_meshtags(cell_tags)
        if facet_tags is not None:
            xdmf.write_meshtags(facet_tags)
    return path


# ------------------------------------------- mesh motion, XDMF of functions
# (added for geometry/remap.py and workflow/render.py: the worn geometry)

def _cpp_mesh(mesh):
    """The C++ mesh behind a Python ``Mesh`` (Debian 0.5.2 keeps it in ``_mesh``)."""
    return getattr(mesh, "_mesh", getattr(mesh, "_cpp_object", mesh))


def cell_geometry_nodes(mesh) -> np.ndarray:
    """(n_local_cells, nodes_per_cell) geometry node indices of each cell, in
    the coordinate element's (basix) order: vertices first, then edges."""
    tdim = mesh.topology.dim
    n = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
    dm = mesh.geometry.dofmap
    return np.asarray(dm.array, dtype=np.int64).reshape(n, -1)


def geometry_node_blocks(V) -> np.ndarray:
    """For each geometry node, the block (node) index of ``V`` at the same place.

    ``V`` must be a Lagrange space of the coordinate element's degree, whose
    cell DOFs then sit on the geometry nodes in the same local order.
    """
    mesh = V.mesh
    if V.ufl_element().degree() != geometry_degree(mesh):
        raise ValueError(f"space of degree {V.ufl_element().degree()} does not match the geometry "
                         f"(degree {geometry_degree(mesh)})")
    geom = cell_geometry_nodes(mesh)
    dofs = np.asarray(V.dofmap.list.array, dtype=np.int64).reshape(geom.shape[0], -1)
    out = np.full(mesh.geometry.x.shape[0], -1, dtype=np.int64)
    out[geom.ravel()] = dofs.ravel()
    return out


def exterior_facets(mesh) -> np.ndarray:
    """Local indices of the facets on the boundary of the mesh (each body's surface)."""
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, tdim)
    return np.asarray(dolfinx.mesh.exterior_facet_indices(mesh.topology), dtype=np.int32)


def facet_vertex_nodes(mesh, facets) -> np.ndarray:
    """(n_facets, 3) geometry node indices at the vertices of triangle facets
    (0.5.2's ``entities_to_geometry`` returns only the vertex nodes of P2 facets)."""
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, tdim)
    facets = np.asarray(facets, dtype=np.int32)
    if facets.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    return np.asarray(dolfinx.cpp.mesh.entities_to_geometry(_cpp_mesh(mesh), tdim - 1, facets, False),
                      dtype=np.int64)


def blocks_of_facets(V, facets) -> np.ndarray:
    """Local block indices of every DOF on the given local facets."""
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, mesh.topology.dim)
    return np.asarray(fem.locate_dofs_topological(V, fdim, np.asarray(facets, dtype=np.int32)), dtype=np.int64)


def solve_with_dirichlet(a, L, V, blocks: np.ndarray, values: np.ndarray):
    """Solve ``a(u, v) = L(v)`` with ``u`` = ``values`` (n_blocks, bs) at the local
    ``blocks`` of ``V``; a direct LU solve (MUMPS if PETSc has it). Returns the Function."""
    g = fem.Function(V)
    bs = block_size(V)
    g.x.array.reshape(-1, bs)[np.asarray(blocks)] = np.asarray(values).reshape(len(blocks), bs)
    bc = fem.dirichletbc(g, np.asarray(blocks, dtype=np.int32))
    opts = {"ksp_type": "preonly", "pc_type": "lu"}
    if _has_mumps_solver():
        opts["pc_factor_mat_solver_type"] = "mumps"
    problem = dolfinx.fem.petsc.LinearProblem(a, L, bcs=[bc], petsc_options=opts)
    u = problem.solve()
    u.x.scatter_forward()
    return u


def _has_mumps_solver() -> bool:
    try:
        from reduction.eigen import _has_mumps

        return bool(_has_mumps())
    except Exception:  # pragma: no cover - depends on the PETSc build
        return False


def set_geometry(mesh, x: np.ndarray) -> None:
    """Overwrite the mesh's geometry node coordinates (N, 3) [m] in place."""
    mesh.geometry.x[:, : x.shape[1]] = x


class moved:
    """Context manager: the mesh's geometry at ``x`` (N, 3) [m] inside, restored after."""

    def __init__(self, mesh, x):
        self.mesh, self.x = mesh, np.asarray(x)

    def __enter__(self):
        self.saved = np.array(self.mesh.geometry.x, copy=True)
        set_geometry(self.mesh, self.x)
        return self.mesh

    def __exit__(self, *exc):
        self.mesh.geometry.x[:] = self.saved
        return False


def vtk_mesh(mesh_or_space):
    """``(cells, cell_types, points)`` for a pyvista ``UnstructuredGrid`` (points =
    geometry nodes for a mesh, DOF coordinates for a space)."""
    return dolfinx.plot.create_vtk_mesh(mesh_or_space)


def read_mesh_xdmf(path: str | Path, comm=MPI.COMM_WORLD, mesh_name: str = "mesh",
                   cell_tags: str = "cell_tags", facet_tags: str = "facet_tags"):
    """Read ``(mesh, cell_tags, facet_tags)`` written by :func:`write_mesh_xdmf`.

    A tag set absent from the file is returned as None.
    """
    path = Path(path)
    if not path.is_file():
        raise GeometryError(f"mesh file {path} does not exist")
    with dolfinx.io.XDMFFile(comm, str(path), "r") as xdmf:
        mesh = xdmf.read_mesh(name=mesh_name)
        mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
        tags = []
        for name in (cell_tags, facet_tags):
            try:
                t = xdmf.read_meshtags(mesh, name)
                t.name = name
            except RuntimeError:
                t = None
            tags.append(t)
    return mesh, tags[0], tags[1]


def write_functions_xdmf(path: str | Path, mesh, functions, cell_tags=None, facet_tags=None, t: float = 0.0) -> Path:
    """Mesh, optional tags and Lagrange functions of the geometry's degree to ``path``
    (.xdmf + .h5 beside it; ParaView reads it)."""
    path = Path(path)
    mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
    with dolfinx.io.XDMFFile(mesh.comm, str(path), "w") as xdmf:
        xdmf.write_mesh(mesh)
        for tags in (cell_tags, facet_tags):
            if tags is not None:
                xdmf.write_meshtags(tags)
        for f in functions:
            xdmf.write_function(f, t)
    return path


def cellwise_function(mesh, values: np.ndarray, name: str = "c"):
    """A piecewise-constant (DG0) Function with ``values`` (n_local_cells,) per cell."""
    Q = fem.FunctionSpace(mesh, ("DG", 0))
    f = function(Q, name)
    dofs = np.asarray(Q.dofmap.list.array, dtype=np.int64)
    f.x.array[dofs] = np.asarray(values)[: dofs.size]
    return f
