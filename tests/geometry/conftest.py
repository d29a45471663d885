"""Reading written meshes back with gmsh alone, independently of geometry/."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest


@dataclass
class Group:
    dim: int
    tag: int
    name: str
    elem_types: set = field(default_factory=set)
    conn: np.ndarray | None = None      # (n_el, nodes per element) node tags
    corners: np.ndarray | None = None   # (n_el, vertices per element) node tags


@dataclass
class Mesh:
    """Nodes (tag → xyz) and the physical groups of a .msh file."""
    pos: np.ndarray                      # pos[tag] = xyz
    node_tags: np.ndarray
    groups: dict

    def xyz(self, tags) -> np.ndarray:
        return self.pos[np.asarray(tags, dtype=np.int64)]

    def vertices(self, name) -> np.ndarray:
        return np.unique(self.groups[name].corners)

    def nodes(self, name) -> np.ndarray:
        return np.unique(self.groups[name].conn)


def read_msh(path) -> Mesh:
    """Nodes and physical groups of a .msh file, read with gmsh only."""
    import gmsh

    gmsh.initialize([], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        tags = tags.astype(np.int64)
        pos = np.full((tags.max() + 1, 3), np.nan)
        pos[tags] = xyz.reshape(-1, 3)
        groups = {}
        for dim, tag in gmsh.model.getPhysicalGroups():
            g = Group(dim, tag, gmsh.model.getPhysicalName(dim, tag))
            conns, corners = [], []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                etypes, _, enodes = gmsh.model.mesh.getElements(dim, ent)
                for t, n in zip(etypes, enodes):
                    _, _, _, nn, _, nv = gmsh.model.mesh.getElementProperties(t)
                    g.elem_types.add(int(t))
                    c = np.asarray(n, dtype=np.int64).reshape(-1, nn)
                    conns.append(c)
                    corners.append(c[:, :nv])
            g.conn = np.vstack(conns)
            g.corners = np.vstack(corners)
            groups[g.name] = g
        return Mesh(pos=pos, node_tags=tags, groups=groups)
    finally:
        gmsh.finalize()


@pytest.fixture(name="read_msh", scope="session")
def read_msh_fixture():
    """The reader, for tests (test modules here are not a package)."""
    return read_msh


@pytest.fixture(scope="session")
def default_sector(tmp_path_factory):
    """The default sector, built once: (info, path, Mesh)."""
    from geometry.sector import build_sector

    path = tmp_path_factory.mktemp("sector") / "default.msh"
    info = build_sector(None, path)
    return info, path, read_msh(path)
