"""reduce_bundle: the reduced model's maps, loads, condensation and save/load."""
import numpy as np
import pytest

import lattice
from workflow.engine.condense import condense, recover, relative_coordinates
from reduction.reduce import reduce_bundle, reduce_with_basis
from workflow.engine.model import ReducedModel


@pytest.fixture(scope="module", params=[0, 2], ids=["paired", "grounded"])
def reduced(request):
    bundle = lattice.lattice_bundle(grounded_pairs=request.param)
    model, basis = reduce_with_basis(bundle, 10)
    return bundle, model, basis


def test_B_O_and_loads_are_the_full_maps_through_the_basis(reduced):
    bundle, model, basis = reduced
    q = np.random.default_rng(0).standard_normal(model.size)
    u = basis.expand(q)
    np.testing.assert_allclose(model.B @ q, lattice.contact_operator(bundle) @ u, atol=1e-12 * np.abs(u).max())
    np.testing.assert_allclose(model.O @ q, u[bundle.loads.observe], atol=1e-14)
    np.testing.assert_allclose(model.f_harmonic @ q, bundle.loads.harmonic @ u, rtol=1e-12)
    np.testing.assert_allclose(model.f_static @ q, bundle.loads.static @ u, rtol=1e-12)
    assert model.info["modes"] == 10 and model.info["boundary_dofs"] == basis.boundary.size
    assert {"factor", "constraint_modes", "eigen", "projection", "total"} <= set(model.info["seconds"])


def test_grounded_side_contributes_nothing():
    bundle = lattice.lattice_bundle(grounded_pairs=2)
    model, basis = reduce_with_basis(bundle, 4)
    c = bundle.contact
    k = c.n_pairs - 1  # grounded pair: u_r = R u_blade
    q = np.random.default_rng(1).standard_normal(model.size)
    u = basis.expand(q)
    np.testing.assert_allclose(model.B[3 * k:3 * k + 3] @ q, c.frames()[k] @ u[c.blade_dofs[k]], atol=1e-14)


def test_save_load_round_trip(tmp_path, reduced):
    _, model, _ = reduced
    path = model.save(tmp_path / "reduced.npz")
    back = ReducedModel.load(path)
    for k in ("M", "K", "C", "B", "O", "f_static", "f_harmonic", "gap", "area", "position"):
        np.testing.assert_array_equal(getattr(back, k), getattr(model, k))
    assert back.info["fixed_interface_hz"] == model.info["fixed_interface_hz"]


def _spring_solutions(bundle, model, omega, kc):
    """Observed response at harmonic 1: full direct solve vs condensation with λ = k_c u_r."""
    S = lattice.contact_operator(bundle).toarray()
    free = bundle.free_dofs
    D = (bundle.K - omega ** 2 * bundle.M + 1j * omega * bundle.C).toarray() + S.T @ (kc[:, None] * S)
    D, f = D[np.ix_(free, free)], bundle.loads.harmonic[free]
    u = np.zeros(bundle.n_dofs, complex)
    u[free] = np.linalg.solve(D, f)
    rc = relative_coordinates(model)
    cond = condense(rc, omega, nh=1)
    Ur = np.zeros((2, kc.size), complex)
    Ur[1] = np.linalg.solve(cond.Zr[1] + np.diag(kc), cond.Fr[1])  # Z_r U_r + λ = F_r, λ = k_c u_r
    return u[bundle.loads.observe], recover(rc, omega, Ur)[1]


def test_condensation_with_linear_contact_springs_matches_full_solve():
    """All fixed-interface modes kept: the reduction is exact, so must be the condensed solve."""
    bundle = lattice.lattice_bundle()
    n_interior = bundle.free_dofs.size - reduce_with_basis(bundle, 2)[1].boundary.size
    model = reduce_bundle(bundle, n_interior)
    kc = np.tile([4e6, 1e6, 1e6], bundle.contact.n_pairs)
    for omega in (0.0, 2 * np.pi * 150.0, 2 * np.pi * 900.0):
        full, red = _spring_solutions(bundle, model, omega, kc)
        np.testing.assert_allclose(red, full, rtol=1e-8, atol=1e-10 * np.abs(full).max())


def test_condensation_with_springs_truncated_basis_is_close_and_static_exact():
    bundle = lattice.lattice_bundle()
    model = reduce_bundle(bundle, 30)
    kc = np.tile([4e6, 1e6, 1e6], bundle.contact.n_pairs)
    full, red = _spring_solutions(bundle, model, 0.0, kc)  # static: exact with any mode count
    np.testing.assert_allclose(red, full, rtol=1e-9)
    full, red = _spring_solutions(bundle, model, 2 * np.pi * 200.0, kc)
    assert np.abs(red - full).max() < 1e-2 * np.abs(full).max()


def test_the_projections_by_column_blocks_are_the_whole_products(monkeypatch, reduced):
    """The constraint modes solved and the VᵀAV projections formed a few columns at a time (to keep
    the n × m products from being whole) give the model of the whole products: VᵀMV, VᵀKV, VᵀCV
    against the dense products of the same basis, to round-off; the constraint modes and the
    reduced model's frequencies against the default blocks (the fixed-interface modes' signs and
    degenerate pairs may differ between two Lanczos runs, so V's modal columns are not compared)."""
    import scipy.linalg

    import reduction.craig_bampton as cb
    import reduction.reduce as rr

    bundle, model, basis = reduced
    monkeypatch.setattr(rr, "PROJECTION_COLUMNS", 3)
    monkeypatch.setattr(cb, "_CHUNK", 2)
    small, small_basis = reduce_with_basis(bundle, 10)
    nb = basis.boundary.size
    assert basis.V.shape[1] > 3 * rr.PROJECTION_COLUMNS and nb > 4 * cb._CHUNK
    free, V = bundle.free_dofs, small_basis.V
    for name in "MKC":
        A = getattr(bundle, name).tocsr()[free][:, free]
        whole = V.T @ (A @ V)
        np.testing.assert_allclose(getattr(small, name), 0.5 * (whole + whole.T), rtol=0,
                                   atol=1e-12 * np.abs(whole).max(), err_msg=name)
    np.testing.assert_allclose(V[:, :nb], basis.V[:, :nb], rtol=0, atol=1e-12 * np.abs(basis.V[:, :nb]).max())
    w_small = scipy.linalg.eigh(small.K, small.M, eigvals_only=True)    # ω² [rad²/s²], rigid modes ≈ 0
    w = scipy.linalg.eigh(model.K, model.M, eigvals_only=True)
    np.testing.assert_allclose(w_small, w, rtol=1e-9, atol=1e-12 * w.max())
