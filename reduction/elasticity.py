"""UFL forms of isotropic linear elasticity in a frame rotating about x.

All forms are on a vector Lagrange space ``V``; SI units (Pa, kg/m³, rad/s).
The rotating-frame terms follow DESIGN §3 "Preload":
``K(Ω) = K₀ + K_σ(σ₀) − Ω² M_⊥`` with the centrifugal body force
``ρ Ω² r_⊥``, ``r_⊥ = (0, y, z)`` (engine axis = x through the origin,
contracts §1). Coriolis (gyroscopic) coupling is not modelled: it is
skew-symmetric and small for a blade vibrating mostly flapwise.
"""
from __future__ import annotations

import ufl

# P = projector onto the plane normal to the rotation axis x.
_P = ufl.as_matrix([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def lame(young: float, poisson: float) -> tuple[float, float]:
    """(λ, μ) [Pa] from Young's modulus [Pa] and Poisson's ratio."""
    mu = young / (2.0 * (1.0 + poisson))
    lmbda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    return lmbda, mu


def strain(u):
    return ufl.sym(ufl.grad(u))


def stress(u, young: float, poisson: float):
    """Cauchy stress σ(u) = 2μ ε + λ tr(ε) I [Pa]."""
    lmbda, mu = lame(young, poisson)
    eps = strain(u)
    return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(len(u))


def stiffness(V, young, poisson, dx):
    """K₀: ∫ σ(u) : ε(v) dx."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    return ufl.inner(stress(u, young, poisson), strain(v)) * dx


def mass(V, density, dx):
    """M: ∫ ρ u · v dx."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    return density * ufl.inner(u, v) * dx


def spin_mass(V, density, dx):
    """M_⊥: ∫ ρ P u · P v dx (spin softening enters as −Ω² M_⊥)."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    return density * ufl.inner(ufl.dot(_P, u), ufl.dot(_P, v)) * dx


def geometric_stiffness(V, sigma0, dx):
    """K_σ: ∫ σ₀ : (∇v)ᵀ ∇u dx = ∫ Σ ∂_j u_i σ₀_jk ∂_k v_i dx (stress stiffening)."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    return ufl.inner(ufl.dot(ufl.grad(u), sigma0), ufl.grad(v)) * dx


def centrifugal_load(V, rho_omega2, dx):
    """∫ ρ Ω² r_⊥ · v dx [N], r_⊥ = (0, y, z).

    ``rho_omega2`` = ρΩ² [kg/(m³ s²)]; pass a dolfinx Constant so that Ω = 0
    keeps a (zero) form instead of UFL simplifying it away, and one compiled
    form serves every speed.
    """
    v = ufl.TestFunction(V)
    x = ufl.SpatialCoordinate(V.mesh)
    r = ufl.as_vector([0.0, x[1], x[2]])
    return rho_omega2 * ufl.inner(r, v) * dx


def traction_load(V, traction, ds):
    """∫ t · v ds [N] for a constant traction vector t [Pa] (a dolfinx Constant) on ``ds``."""
    v = ufl.TestFunction(V)
    return ufl.inner(traction, v) * ds

