"""The "linear" contact layout: vertex pairs, P1 areas, midside ties eliminated exactly by the reduction."""
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import TI
from reduction import dolfinx_compat as dc
from reduction.bundle import Contact, Loads
from reduction.pairs import contact_pairs
from reduction.reduce import reduce_bundle, reduce_with_basis
from workflow.errors import BundleError


@pytest.fixture(scope="module")
def layouts(dovetail_mesh):
    mesh, _, ft = dovetail_mesh
    V = dc.vector_space(mesh, 2)
    return {k: contact_pairs(V, ft, nodes=k) for k in ("vertices", "all", "linear")}


@pytest.fixture(scope="module")
def linear_bundle(dovetail, dovetail_mesh):
    from reduction.assemble import build_bundle

    info = dict(dovetail[1], params=dict(contact_nodes="linear"))
    b, _ = build_bundle(*dovetail_mesh, info, TI, damping=dict(modal_ratio=0.002))
    return b


def test_linear_layout_pairs_the_vertices_with_p1_areas_and_ties_every_midside(layouts):
    v, a, lin = layouts["vertices"], layouts["all"], layouts["linear"]
    np.testing.assert_allclose(lin["position"], v["position"], atol=1e-15)
    np.testing.assert_array_equal(lin["blade_dofs"], v["blade_dofs"])
    np.testing.assert_array_equal(lin["disk_dofs"], v["disk_dofs"])
    # A/12 + 2·(A/4)/2 = A/3 per facet and vertex: the P1 areas ∫ φ_i ds of the vertex layout.
    np.testing.assert_allclose(lin["area"], v["area"], rtol=1e-12)
    assert lin["area"].sum() == pytest.approx(a["area"].sum(), rel=1e-13)
    mids = (~a["vertex"]).sum()
    assert lin["tie"].shape == (6 * mids, 3)          # 3 components × (blade, disk) per midside node
    dep = lin["tie"][:, 0]
    assert len(np.unique(dep)) == len(dep)
    assert np.isin(lin["tie"][:, 1:], np.concatenate([v["blade_dofs"].ravel(), v["disk_dofs"].ravel()])).all()


def test_tied_midsides_sit_at_their_edge_midpoints(layouts, dovetail_mesh):
    """Each tied node is the midpoint of its masters (the flank facets are straight-sided)."""
    mesh, _, _ = dovetail_mesh
    X = dc.gather_block_coordinates(dc.vector_space(mesh, 2))
    t = layouts["linear"]["tie"]
    np.testing.assert_allclose(X[t[:, 0] // 3], 0.5 * (X[t[:, 1] // 3] + X[t[:, 2] // 3]), atol=1e-12)


def _constrained_by_hand(b):
    """The same structure with the tied DOFs eliminated from the full matrices (u = T v)."""
    n, t = b.n_dofs, np.asarray(b.contact.tie)
    kept = np.setdiff1d(np.arange(n), t[:, 0])
    col = -np.ones(n, np.int64)
    col[kept] = np.arange(kept.size)
    T = sp.lil_matrix((n, kept.size))
    T[kept, col[kept]] = 1.0
    for d, i, j in t:
        T[d, col[i]] += 0.5
        T[d, col[j]] += 0.5
    T = T.tocsr()
    c, L = b.contact, b.loads
    return replace(b, M=(T.T @ b.M @ T).tocsr(), K=(T.T @ b.K @ T).tocsr(), C=(T.T @ b.C @ T).tocsr(),
                   contact=replace(c, blade_dofs=col[c.blade_dofs], disk_dofs=col[c.disk_dofs], tie=None),
                   loads=Loads(fixed=col[L.fixed], static=T.T @ L.static, harmonic=T.T @ L.harmonic,
                               observe=col[L.observe]), coords=None, path=None)


@pytest.mark.slow  # 4–6 s: make test-slow, to keep make test within 3 minutes on 2 cores
def test_eliminating_ties_after_craig_bampton_is_the_reduction_of_the_constrained_model(linear_bundle):
    """Same fixed-interface modes, constraint modes Ψ_a + ½ΣΨ_dep: equal reduced models to round-off."""
    from workflow.engine.condense import condense, relative_coordinates

    a = reduce_bundle(linear_bundle, 12)
    b = reduce_bundle(_constrained_by_hand(linear_bundle), 12)
    assert a.size == b.size and a.info["tied_dofs"] == linear_bundle.contact.tie.shape[0]
    for w in (0.0, 2 * np.pi * 200.0, 2 * np.pi * 1500.0):   # the interface's dynamic stiffness and load
        ca, cb = condense(relative_coordinates(a), w, 1), condense(relative_coordinates(b), w, 1)
        np.testing.assert_allclose(ca.Zr, cb.Zr, rtol=1e-7, atol=1e-7 * np.abs(cb.Zr).max())
        np.testing.assert_allclose(ca.Fr, cb.Fr, rtol=1e-7, atol=1e-7 * np.abs(cb.Fr).max())


@pytest.mark.slow  # 4–6 s: make test-slow, to keep make test within 3 minutes on 2 cores
def test_the_basis_carries_the_ties_to_the_full_displacement(linear_bundle):
    """Any reduced state expands to a full field whose midside DOFs are their edges' means."""
    model, basis = reduce_with_basis(linear_bundle, 12)
    q = np.random.default_rng(0).standard_normal(model.size)
    u = basis.expand(q)
    t = linear_bundle.contact.tie
    np.testing.assert_allclose(u[t[:, 0]], 0.5 * (u[t[:, 1]] + u[t[:, 2]]), atol=1e-12 * np.abs(u).max())
    assert not np.isin(t[:, 0], basis.boundary).any()


def test_tied_interface_is_stiffer_than_every_node_and_vertex_contact(dovetail, dovetail_mesh, linear_bundle):
    """Rayleigh: each layout adds constraints to the previous one (vertices ⊂ all ⊂ linear), so the
    first tied frequency of the full model can only rise."""
    from reduction.assemble import build_bundle
    from reduction.modes import modes

    f = {}
    for k in ("vertices", "all"):
        b, _ = build_bundle(*dovetail_mesh, dict(dovetail[1], params=dict(contact_nodes=k)), TI,
                            damping=dict(modal_ratio=0.0))
        f[k] = modes(b, 1, tied=True)[0][0]
    f["linear"] = modes(linear_bundle, 1, tied=True)[0][0]
    assert f["vertices"] < f["all"] < f["linear"]


def test_a_tie_on_a_contact_dof_or_out_of_range_is_refused():
    from reduction.bundle import Bundle, validate

    n = 12
    eye = sp.identity(n, format="csr")
    c = Contact(blade_dofs=np.array([[0, 1, 2]]), disk_dofs=np.array([[3, 4, 5]]), normal=np.array([[1.0, 0, 0]]),
                t1=np.array([[0, 1.0, 0]]), t2=np.array([[0, 0, 1.0]]), area=np.ones(1), gap=np.zeros(1),
                tie=np.array([[6, 0, 3]]))
    b = Bundle(M=eye, K=eye, C=eye * 0, contact=c, loads=Loads(fixed=np.array([11]), static=np.zeros(n),
                                                               harmonic=np.zeros(n), observe=np.zeros(0, int)))
    validate(b)
    for bad, what in (([[0, 1, 3]], "dependent"), ([[6, 7, 3]], "master"), ([[6, 0, 99]], "outside"),
                      ([[11, 0, 3]], "dependent")):
        with pytest.raises(BundleError, match=what):
            validate(replace(b, contact=replace(c, tie=np.array(bad))))
