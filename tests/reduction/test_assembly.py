"""Assembly physics: mass, rigid modes, beam frequencies, rotating-beam (Southwell) shifts."""
import numpy as np
import pytest

import meshes
from conftest import TI
from reduction import dolfinx_compat as dc
from reduction.assemble import assemble_operators, clamped_dofs, modal_beta
from reduction.eigen import eigs
from reduction.prestress import tie_map

NO_PAIRS = np.zeros((0, 3), np.int64)


def _clamped_eigs(ops, V, ft, n):
    T = tie_map(ops.M.shape[0], clamped_dofs(V, ft), NO_PAIRS, NO_PAIRS)
    w2, phi = eigs(T.T @ ops.K @ T, T.T @ ops.M @ T, n, 0.0)
    return w2, T @ phi


def test_mass_is_density_times_volume(dovetail, dovetail_mesh):
    _, info = dovetail
    ops, _ = assemble_operators(*dovetail_mesh, TI)
    vol = info["volume_blade_m3"] + info["volume_disk_m3"]
    for c in range(3):  # each component carries the whole mass
        assert ops.M[c::3, c::3].sum() == pytest.approx(TI["density"] * vol, rel=1e-10)


def test_free_two_bodies_have_twelve_rigid_modes(tmp_path):
    path = tmp_path / "coarse.msh"
    meshes.dovetail_msh(path, h=0.008)
    ops, _ = assemble_operators(*dc.read_msh(path), TI)
    np.testing.assert_allclose((ops.K - ops.K.T).data, 0.0, atol=1e-6 * abs(ops.K).max())
    w2, _ = eigs(ops.K, ops.M, 14, sigma=-1e4, vectors=False)
    scale = w2[-1]
    assert np.all(np.abs(w2[:12]) < 1e-8 * scale), w2
    assert w2[12] > 1e-2 * scale, w2


@pytest.mark.parametrize("h, tol", [(0.01, 0.01), (0.005, 0.006),
                                    pytest.param(0.002, 0.004, marks=pytest.mark.slow)])
def test_cantilever_matches_euler_bernoulli(tmp_path, h, tol):
    L, b, t = 0.2, 0.01, 0.005  # bending about y (thin in z): L/t = 40, shear negligible
    meshes.bar_msh(tmp_path / "bar.msh", (L, b, t), h)
    mesh, ct, ft = dc.read_msh(tmp_path / "bar.msh")
    ops, V = assemble_operators(mesh, ct, ft, TI)
    w2, _ = _clamped_eigs(ops, V, ft, 1)
    f_eb = 1.875104 ** 2 * np.sqrt(TI["young"] * t ** 2 / 12 / (TI["density"] * L ** 4)) / (2 * np.pi)
    assert np.sqrt(w2[0]) / (2 * np.pi) == pytest.approx(f_eb, rel=tol)


@pytest.fixture(scope="module")
def radial_bar(tmp_path_factory):
    """Bar along z (radial) from r = 0, thin in x (flapwise) and 2× wider in y (lead-lag)."""
    path = tmp_path_factory.mktemp("radial") / "bar.msh"
    meshes.bar_msh(path, (0.004, 0.008, 0.1), 0.004, axis=2)
    return dc.read_msh(path)


def _flap_lag(radial_bar, omega, **flags):
    """ω² [rad²/s²] of the first flapwise (x) and lead-lag (y) modes."""
    mesh, ct, ft = radial_bar
    ops, V = assemble_operators(mesh, ct, ft, TI, omega, **flags)
    w2, phi = _clamped_eigs(ops, V, ft, 2)
    tip = int(np.argmin(np.linalg.norm(dc.gather_block_coordinates(V) - [0, 0, 0.1], axis=1)))
    direction = np.abs(phi[3 * tip:3 * tip + 3]).argmax(axis=0)
    assert sorted(direction) == [0, 1]
    return w2[list(direction).index(0)], w2[list(direction).index(1)]


def test_rotating_beam_follows_southwell(radial_bar):
    """Southwell: ω² ≈ ω₀² + 1.193 Ω² flapwise, ω₀² + 0.193 Ω² lead-lag (spin softening −Ω²)."""
    flap0, lag0 = _flap_lag(radial_bar, 0.0)
    omega = 1500.0  # rad/s: flapwise shift ≈ 65 % of ω₀²
    flap, lag = _flap_lag(radial_bar, omega)
    assert (flap - flap0) / omega ** 2 == pytest.approx(1.193, rel=0.01)
    assert (lag - lag0) / omega ** 2 == pytest.approx(0.193, rel=0.03)
    # Without spin softening the in-plane mode stiffens like the flapwise one.
    _, lag_ks = _flap_lag(radial_bar, omega, spin_softening=False)
    assert (lag_ks - lag0) / omega ** 2 == pytest.approx(1.193, rel=0.02)
    # And with neither term, rotation leaves K = K₀.
    flap_none, _ = _flap_lag(radial_bar, omega, spin_softening=False, stress_stiffening=False)
    assert flap_none == pytest.approx(flap0, rel=1e-12)


def test_zero_speed_gives_plain_stiffness(radial_bar):
    mesh, ct, ft = radial_bar
    ops, _ = assemble_operators(mesh, ct, ft, TI, 0.0)
    assert ops.K_sigma is None and ops.M_perp is None and not np.any(ops.f_static)
    assert abs(ops.K - ops.K0).max() == 0.0


def test_static_tip_force_at_zero_speed(radial_bar):
    """Excitation.static_force: a +z tip traction summing to the force, stiffening the bar in tension."""
    mesh, ct, ft = radial_bar
    ops, _ = assemble_operators(mesh, ct, ft, TI, 0.0, static_force=500.0)
    np.testing.assert_allclose(ops.f_static.reshape(-1, 3).sum(axis=0), [0, 0, 500.0], atol=1e-9)
    assert ops.K_sigma is not None
    # Tension P along the bar: u0_z(tip) = P L / (E A); the clamp stops the
    # Poisson contraction at the root, which stiffens the bar by ~0.3 %.
    assert ops.u0[2::3].max() == pytest.approx(500.0 * 0.1 / (TI["young"] * 0.004 * 0.008), rel=5e-3)


def test_modal_beta():
    assert modal_beta(0.01, 100.0) == pytest.approx(2e-4)
    assert modal_beta(0.0, 100.0) == 0.0


@pytest.mark.slow
def test_southwell_fine_mesh_small_speed(tmp_path):
    """At Ω ≪ ω₀ on a finer mesh the coefficients approach 1.193 / 0.193 closely."""
    meshes.bar_msh(tmp_path / "bar.msh", (0.004, 0.008, 0.1), 0.002, axis=2)
    bar = dc.read_msh(tmp_path / "bar.msh")
    flap0, lag0 = _flap_lag(bar, 0.0)
    flap, lag = _flap_lag(bar, 1000.0)
    assert (flap - flap0) / 1e6 == pytest.approx(1.193, rel=0.004)
    assert (lag - lag0) / 1e6 == pytest.approx(0.193, rel=0.015)
