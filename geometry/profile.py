"""The dovetail profile in the y–z plane, computed analytically (no gmsh).

The same numbers drive the gmsh model (``geometry.sector``) and the tests'
analytic checks (slot area, disk volume), so they cannot drift apart. All
points are ``(y, z)`` in metres; the profile is extruded along x.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Dovetail:
    """Key points of the half profile y ≥ 0 (mirror for y < 0).

    ``C0`` where the blade's neck meets its inclined face, ``C1``–``C2`` the
    contact flank, ``C3`` the lobe corner; ``T`` where the disk's neck face
    meets the rim top r = r_out. See ``geometry.params`` for the sketch.
    """

    r_in: float
    r_out: float
    half_angle: float          # half the sector angle, rad
    a: float                   # half neck width, m
    b: float                   # half lobe width, m
    beta: float                # flank angle below the y axis, rad
    c: float                   # clearance, m
    flank_length: float        # m
    C0: tuple[float, float]
    C1: tuple[float, float]
    C2: tuple[float, float]
    C3: tuple[float, float]
    T: tuple[float, float]
    z_blade_bottom: float
    z_slot_bottom: float
    y_slot_side: float
    z_platform_bottom: float
    z_platform_top: float
    half_platform: float

    @classmethod
    def from_params(cls, p) -> "Dovetail":
        """Build from a :class:`geometry.params.SectorParams`."""
        a, b, beta, c = 0.5 * p.neck_width, 0.5 * p.lobe_width, p.flank_angle, p.clearance
        z0 = p.r_out - p.neck_height
        z3 = z0 - (b - a) * math.tan(beta)
        inclined = (b - a) / math.cos(beta)
        relief = 0.5 * (inclined - p.flank_length)
        u = (math.cos(beta), -math.sin(beta))          # along the face, C0 → C3
        C1 = (a + relief * u[0], z0 + relief * u[1])
        C2 = (b - relief * u[0], z3 - relief * u[1])
        # Outside the flank the blade's face turns away from the disk by the
        # relief angle (as real dovetails do at the edges of bedding). Kept
        # collinear, the three faces would be coplanar and the mesher leaves
        # flat tetrahedra across their common edges.
        rho = p.relief_angle
        C0 = (a, C1[1] + (C1[0] - a) * math.tan(beta - rho))
        C3 = (b, C2[1] - (b - C2[0]) * math.tan(beta + rho))
        yT = a + c
        T = (yT, math.sqrt(max(p.r_out ** 2 - yT ** 2, 0.0)))
        z_bot = C3[1] - p.lobe_height
        zpb = p.r_out + p.shank_height
        return cls(r_in=p.r_in, r_out=p.r_out, half_angle=math.pi / p.n_sectors, a=a, b=b, beta=beta,
                   c=c, flank_length=p.flank_length, C0=C0, C1=C1, C2=C2, C3=C3, T=T,
                   z_blade_bottom=z_bot, z_slot_bottom=z_bot - c, y_slot_side=b + c,
                   z_platform_bottom=zpb, z_platform_top=zpb + p.platform_thickness,
                   half_platform=0.5 * p.platform_width)

    @property
    def inclined_length(self) -> float:
        """Length of the reference inclined face (neck to lobe, before the
        reliefs), m: the flank is its middle part."""
        return (self.b - self.a) / math.cos(self.beta)

    @property
    def relief(self) -> float:
        """Length of the inclined face outside the contact flank at each end, m."""
        return 0.5 * (self.inclined_length - self.flank_length)

    # ---- outlines (counter-clockwise in the (y, z) plane) ----

    def blade_outline(self) -> np.ndarray:
        """Root + shank + platform polygon, (n, 2) [y, z], straight edges."""
        zb, zpb, zpt, wp = self.z_blade_bottom, self.z_platform_bottom, self.z_platform_top, self.half_platform
        right = [(self.b, zb), self.C3, self.C2, self.C1, self.C0, (self.a, zpb), (wp, zpb), (wp, zpt)]
        return _mirror_close(right)

    def slot_polygon(self) -> np.ndarray:
        """The slot below the chord T'–T, (n, 2) [y, z], straight edges.

        The slot is this polygon plus the circular segment of r_out above the
        chord (see :meth:`slot_area`).
        """
        ys, zs, z2 = self.y_slot_side, self.z_slot_bottom, self.C2[1]
        right = [(ys, zs), (ys, z2), self.C2, self.C1, self.T]
        return _mirror_close(right)

    def disk_outline(self) -> list[tuple[str, tuple[float, float]]]:
        """Closed outline of the disk rim sector as ``(kind, point)``, where
        ``kind`` ('line' or 'arc', centre at the origin) is how the outline
        arrives at ``point`` from the previous one. Starts at the inner
        right corner and runs counter-clockwise."""
        s, co = math.sin(self.half_angle), math.cos(self.half_angle)
        ys, zs, z2 = self.y_slot_side, self.z_slot_bottom, self.C2[1]
        m = lambda q: (-q[0], q[1])
        seq = [("arc", (self.r_in * s, self.r_in * co)),       # from the inner left corner
               ("line", (self.r_out * s, self.r_out * co)),
               ("arc", self.T),
               ("line", self.C1),
               ("line", self.C2),
               ("line", (ys, z2)),
               ("line", (ys, zs)),
               ("line", (-ys, zs)),
               ("line", (-ys, z2)),
               ("line", m(self.C2)),
               ("line", m(self.C1)),
               ("line", m(self.T)),
               ("arc", (-self.r_out * s, self.r_out * co)),
               ("line", (-self.r_in * s, self.r_in * co))]
        return seq

    # ---- analytic areas (m²) ----

    def slot_area(self) -> float:
        """Area of the slot: polygon below the chord T'–T plus the circular
        segment of radius r_out above it."""
        phi = 2.0 * math.asin(self.T[0] / self.r_out)
        segment = 0.5 * self.r_out ** 2 * (phi - math.sin(phi))
        return polygon_area(self.slot_polygon()) + segment

    def disk_area(self) -> float:
        """Area of the rim sector's profile: annular sector minus slot."""
        return self.half_angle * (self.r_out ** 2 - self.r_in ** 2) - self.slot_area()

    def root_area(self) -> float:
        """Area of the blade's root + shank + platform profile."""
        return polygon_area(self.blade_outline())

    # ---- the flanks ----

    def flank_segments(self) -> dict[str, tuple[tuple[float, float], tuple[float, float]]]:
        """Contact flank ends (C1, C2) for each side. Intrados is y < 0,
        extrados y > 0 (the airfoil's camber is convex towards +y)."""
        m = lambda q: (-q[0], q[1])
        return {"intrados": (m(self.C1), m(self.C2)), "extrados": (self.C1, self.C2)}

    def flank_normals(self) -> dict[str, tuple[float, float, float]]:
        """Unit normal (x, y, z) of each flank, pointing from the disk into the
        blade (mostly −z: the blade lobes push radially outward on the disk)."""
        sb, cb = math.sin(self.beta), math.cos(self.beta)
        return {"intrados": (0.0, sb, -cb), "extrados": (0.0, -sb, -cb)}


def polygon_area(pts: np.ndarray) -> float:
    """Shoelace area of a closed polygon given without the repeated vertex."""
    y, z = np.asarray(pts, dtype=float).T
    return 0.5 * float(np.dot(y, np.roll(z, -1)) - np.dot(z, np.roll(y, -1)))


def _mirror_close(right: list[tuple[float, float]]) -> np.ndarray:
    """Right half (from bottom to top) → full counter-clockwise polygon."""
    left = [(-y, z) for (y, z) in reversed(right)]
    return np.array(right + left, dtype=float)
