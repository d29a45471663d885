"""The clamped bar used to test the assembly against Euler–Bernoulli."""
from __future__ import annotations

import numpy as np
import pytest

from geometry.bar import build_bar
from workflow.errors import GeometryError


def test_bar_groups_faces_and_tip_vertex(tmp_path, read_msh):
    L, w, t = 0.2, 0.02, 0.01
    info = build_bar(L, w, t, 0.005, tmp_path / "bar.msh")
    mesh = read_msh(tmp_path / "bar.msh")
    assert {(g.name, g.dim, g.tag) for g in mesh.groups.values()} == {
        ("blade", 3, 1), ("disk_clamp", 2, 31), ("blade_tip", 2, 41)}
    assert mesh.groups["blade"].elem_types == {11}
    assert info["volume_m3"] == pytest.approx(L * w * t, rel=1e-12)
    assert np.allclose(mesh.xyz(mesh.nodes("disk_clamp"))[:, 0], 0.0)
    tip = mesh.xyz(mesh.vertices("blade_tip"))
    assert np.allclose(tip[:, 0], L)
    assert np.linalg.norm(tip - np.array(info["tip_point"]), axis=1).min() < 1e-14
    assert info["n_nodes"] == len(mesh.node_tags)


def test_bar_first_order(tmp_path, read_msh):
    info = build_bar(0.1, 0.01, 0.01, 0.005, tmp_path / "bar.msh", order=1)
    assert read_msh(tmp_path / "bar.msh").groups["blade"].elem_types == {4}
    assert info["element_order"] == 1


@pytest.mark.parametrize("args,name", [((0.0, 0.01, 0.01, 0.005), "length"),
                                       ((0.1, -0.01, 0.01, 0.005), "width"),
                                       ((0.1, 0.01, 0.01, 1e-6), "'h'")])
def test_bar_bad_parameters(tmp_path, args, name):
    with pytest.raises(GeometryError, match=name):
        build_bar(*args, tmp_path / "bar.msh")
