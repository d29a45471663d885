"""The airfoil: a cambered, twisted plate of constant thickness (no gmsh here).

Section at height z: a parabolic camber line of height ``camber·chord`` at
mid-chord, offset by ±thickness/2 along its normal, blunt at both ends. The
chord is centred at (x, y) = (axial_length/2, 0) — the stacking line is
radial — and turned by the stagger γ(z) = stagger + twist·(z − z_pt)/span
about it, where z_pt is the platform top. Local section frame: ξ along the
chord (leading edge at ξ = −chord/2, towards x = 0), η normal to it; the
camber is convex towards +η, whose y component is positive: +y is the
extrados (suction side), −y the intrados (pressure side).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Points per side of a section (spline interpolation points).
SECTION_POINTS = 11
#: Spanwise sections of the loft above the platform (linear twist → smooth loft).
SPAN_SECTIONS = 5


@dataclass(frozen=True)
class Airfoil:
    """Geometry of the airfoil, m and rad (see the module docstring)."""

    chord: float
    thickness: float
    camber: float
    stagger: float
    twist: float
    span: float
    x_centre: float
    z_root: float      # bottom of the loft, embedded in the platform
    z_platform: float  # platform top, where the span and the twist start
    z_tip: float

    @classmethod
    def from_params(cls, p) -> "Airfoil":
        """Build from a :class:`geometry.params.SectorParams`."""
        from geometry.profile import Dovetail

        zpt = Dovetail.from_params(p).z_platform_top
        # The loft starts half-way into the platform so that the fuse cuts
        # through solid material instead of gluing two coplanar faces.
        return cls(chord=p.chord, thickness=p.thickness, camber=p.camber, stagger=p.stagger,
                   twist=p.twist, span=p.span, x_centre=0.5 * p.axial_length,
                   z_root=zpt - 0.5 * p.platform_thickness, z_platform=zpt, z_tip=zpt + p.span)

    def stagger_at(self, z: float) -> float:
        """Stagger angle γ(z), rad (linear twist from the platform top)."""
        return self.stagger + self.twist * (z - self.z_platform) / self.span

    def stations(self) -> list[float]:
        """Heights of the loft's sections, m (root section first, tip last)."""
        zs = np.linspace(self.z_platform, self.z_tip, SPAN_SECTIONS)
        return [self.z_root] + [float(z) for z in zs]

    def _to_xy(self, xi: np.ndarray, eta: np.ndarray, z: float) -> np.ndarray:
        g = self.stagger_at(z)
        x = self.x_centre + xi * math.cos(g) - eta * math.sin(g)
        y = xi * math.sin(g) + eta * math.cos(g)
        return np.column_stack([x, y, np.full_like(x, z)])

    def section_sides(self, z: float) -> tuple[np.ndarray, np.ndarray]:
        """(upper, lower) surface points at height z, each (SECTION_POINTS, 3),
        from leading to trailing edge. Upper is the +η (extrados) side."""
        s = np.linspace(0.0, 1.0, SECTION_POINTS)
        c, f, t = self.chord, self.camber, self.thickness
        xi = (s - 0.5) * c
        eta_c = 4.0 * f * c * s * (1.0 - s)
        slope = 4.0 * f * (1.0 - 2.0 * s)
        nrm = np.sqrt(1.0 + slope ** 2)
        nx, ny = -slope / nrm, 1.0 / nrm
        up = self._to_xy(xi + 0.5 * t * nx, eta_c + 0.5 * t * ny, z)
        lo = self._to_xy(xi - 0.5 * t * nx, eta_c - 0.5 * t * ny, z)
        return up, lo

    def section_outline(self, eta_span: float) -> np.ndarray:
        """Closed outline (points) of the section at span fraction ``eta_span``
        (0 = platform top, 1 = tip); for fit checks."""
        up, lo = self.section_sides(self.z_platform + eta_span * self.span)
        return np.vstack([up, lo[::-1]])

    def tip_point(self) -> np.ndarray:
        """Mid-chord point of the tip section on the camber line, (3,) m:
        where the excitation is applied."""
        return self._to_xy(np.array([0.0]), np.array([self.camber * self.chord]), self.z_tip)[0]

    def tip_normal(self) -> np.ndarray:
        """Unit vector normal to the tip's chord plane (towards the extrados)."""
        g = self.stagger_at(self.z_tip)
        return np.array([-math.sin(g), math.cos(g), 0.0])
