"""Small model bundles for reduction tests (reusable by any test module).

``make_lattice_bundle(...)`` builds a two-body 3D spring/mass lattice in the
layout of the real sector: a "disk" block clamped at its bottom face and a
"blade" block standing on it, connected ONLY through node-to-node contact
pairs on the shared plane z = 0 (the blade floats when the contact is open).
Every hexahedral cell carries springs between all 28 of its node pairs (a
rigid truss) with consistent bar masses, so M is SPD and the free blade has
exactly 6 rigid-body modes. Contact frames are tilted ±``tilt`` about x like
the two flanks of a dovetail. Loads: a harmonic force at a blade-tip node, a
distributed +z static load on the blade (centrifugal-like), observed DOFs at
the tip. SI units; the numbers are arbitrary but of a plausible scale.

Import it as ``import lattice`` (``tests/reduction/conftest.py`` puts this
folder on ``sys.path``): ``lattice.lattice_bundle(**overrides)``; plus
``contact_operator(bundle)``, the full-size u → u_r map for reference solves.
"""
from __future__ import annotations

import itertools

import numpy as np
import scipy.sparse as sp

from reduction.bundle import Bundle, Contact, Loads


def _grid(nx, ny, nz, h, z0):
    """Node coordinates of an nx×ny×nz grid (x fastest) and its hexahedral cells."""
    idx = np.arange(nx * ny * nz).reshape(nz, ny, nx)
    x, y, z = np.meshgrid(np.arange(nx) * h, np.arange(ny) * h, z0 + np.arange(nz) * h, indexing="xy")
    coords = np.column_stack([np.moveaxis(a, 2, 0).ravel() for a in (x, y, z)])
    cells = []
    for k, j, i in itertools.product(range(nz - 1), range(ny - 1), range(nx - 1)):
        cells.append(idx[k:k + 2, j:j + 2, i:i + 2].ravel())
    return coords, np.array(cells), idx


def _truss(coords, cells, stiffness, line_density):
    """K and M (3N×3N) of springs between all node pairs of every cell.

    Spring axial stiffness ``stiffness·h/L`` [N/m] (h: shortest edge), bar
    mass ``line_density·L`` [kg] lumped consistently (m/6·[[2, 1], [1, 2]]).
    """
    h = np.min(np.linalg.norm(coords[cells[0][1]] - coords[cells[0][0]]))
    rows, cols, kv, mv = [], [], [], []
    for cell in cells:
        for a, b in itertools.combinations(cell, 2):
            d = coords[b] - coords[a]
            L = np.linalg.norm(d)
            e = d / L
            ke = stiffness * h / L * np.outer(e, e)
            me = line_density * L / 6.0
            da, db = 3 * a + np.arange(3), 3 * b + np.arange(3)
            for (ri, ci, sgn, msc) in ((da, da, 1, 2), (db, db, 1, 2), (da, db, -1, 1), (db, da, -1, 1)):
                rr, cc = np.meshgrid(ri, ci, indexing="ij")
                rows.append(rr.ravel())
                cols.append(cc.ravel())
                kv.append((sgn * ke).ravel())
                mv.append((msc * me * np.eye(3)).ravel())
    n = 3 * coords.shape[0]
    r, c = np.concatenate(rows), np.concatenate(cols)
    K = sp.csr_matrix((np.concatenate(kv), (r, c)), shape=(n, n))
    M = sp.csr_matrix((np.concatenate(mv), (r, c)), shape=(n, n))
    return K, M


def lattice_bundle(nx=3, ny=2, nz_blade=5, nz_disk=3, h=0.01, stiffness=1e7, line_density=0.5,
                   alpha=2.0, beta=2e-6, tilt_deg=30.0, grounded_pairs=0, tip_force=(0.3, 1.0, 0.0),
                   static_load=10.0) -> Bundle:
    """A two-body lattice bundle with ``nx·ny`` contact pairs (see module doc).

    ``grounded_pairs``: that many pairs (the last ones) get ``disk_dofs = −1``
    (blade node held against ground). ``alpha``/``beta``: Rayleigh damping
    C = αM + βK. ``static_load`` [N]: total +z force spread over the blade.
    """
    cb, cells_b, idx_b = _grid(nx, ny, nz_blade, h, 0.0)
    cd, cells_d, idx_d = _grid(nx, ny, nz_disk, h, -(nz_disk - 1) * h)
    nb_nodes = cb.shape[0]
    coords = np.vstack([cb, cd])
    cells = np.vstack([cells_b, cells_d + nb_nodes])  # no cell spans the two bodies
    K, M = _truss(coords, cells, stiffness, line_density)
    n = 3 * coords.shape[0]

    blade_bottom = idx_b[0].ravel()  # z = 0, x fastest
    disk_top = idx_d[-1].ravel() + nb_nodes
    disk_bottom = idx_d[0].ravel() + nb_nodes
    # pairs: flank = y index (0 intrados, 1 extrados), then along x, then across
    flank = np.tile(np.arange(ny), (nx, 1)).T.ravel() % 2
    order = np.lexsort((coords[blade_bottom, 1], coords[blade_bottom, 0], flank))
    bnode, dnode, flank = blade_bottom[order], disk_top[order], flank[order]
    a = np.deg2rad(tilt_deg)
    normal = np.where(flank[:, None] == 0, [0.0, -np.sin(a), np.cos(a)], [0.0, np.sin(a), np.cos(a)])
    t1 = np.tile([1.0, 0.0, 0.0], (bnode.size, 1))
    t2 = np.cross(normal, t1)
    blade_dofs = 3 * bnode[:, None] + np.arange(3)
    disk_dofs = 3 * dnode[:, None] + np.arange(3)
    if grounded_pairs:
        disk_dofs[-grounded_pairs:] = -1
    contact = Contact(blade_dofs=blade_dofs, disk_dofs=disk_dofs, normal=normal, t1=t1, t2=t2,
                      area=np.full(bnode.size, h * h), gap=np.zeros(bnode.size), flank=flank,
                      position=coords[bnode].copy())

    tip = idx_b[-1, -1, -1]  # top corner of the blade
    harmonic = np.zeros(n)
    harmonic[3 * tip:3 * tip + 3] = tip_force
    static = np.zeros(n)
    static[3 * np.arange(nb_nodes) + 2] = static_load / nb_nodes
    loads = Loads(fixed=(3 * disk_bottom[:, None] + np.arange(3)).ravel(), static=static, harmonic=harmonic,
                  observe=3 * tip + np.arange(3))
    C = (alpha * M + beta * K).tocsr()
    meta = {"kind": "lattice test bundle", "nx": nx, "ny": ny, "nz_blade": nz_blade, "nz_disk": nz_disk,
            "rayleigh": [alpha, beta]}
    return Bundle(M=M, K=K, C=C, contact=contact, loads=loads, meta=meta, coords=coords)


def contact_operator(bundle: Bundle) -> sp.csr_matrix:
    """(3p, n) map from full displacements to u_r = R (u_blade − u_disk), pair-major."""
    c = bundle.contact
    R = c.frames()
    rows, cols, vals = [], [], []
    for k in range(c.n_pairs):
        for side, sign in ((c.blade_dofs[k], 1.0), (c.disk_dofs[k], -1.0)):
            if side[0] < 0:
                continue
            for a in range(3):
                rows += [3 * k + a] * 3
                cols += list(side)
                vals += list(sign * R[k, a])
    return sp.csr_matrix((vals, (rows, cols)), shape=(3 * c.n_pairs, bundle.n_dofs))
