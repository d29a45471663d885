"""Parameters of the blade–disk sector and their validation.

Every dimension is SI (metres, radians). Coordinates follow
``docs/contracts.md`` §1: x axial (engine axis through the origin, leading
edge at x = 0), z radial at the sector's centre line, y circumferential.

The dovetail is a profile in the y–z plane extruded along x. With
a = neck_width/2, b = lobe_width/2, β = flank_angle, c = clearance, the half
profile y ≥ 0 of the blade root is (the other half is its mirror image)::

    reference inclined face: from (a, r_out − neck_height) down at β to y = b
    C1, C2    the contact flank: the middle flank_length of that face
    C0, C3    neck and lobe corners: outside the flank the blade's face turns
              away from the disk by relief_angle (C1 → C0 at β − ρ, C2 → C3
              at β + ρ), as real dovetails are relieved at the edges of bedding
    blade:  shank y = a up to the platform; C0 → C1 → C2 → C3;
            lobe side y = b down to z(C3) − lobe_height; flat bottom.
    disk:   rim top r = r_out down to T = (a + c, on r = r_out); straight to
            C1 (the neck gap opens from 0 at C1 to c at T); the flank C1 → C2;
            horizontally out to y = b + c; slot side y = b + c down to the slot
            bottom, c below the blade's bottom.

The blade lies below the inclined face, the disk's overhang above it; under
centrifugal load the lobes push radially outward on the overhang through the
flanks. The bodies share only the flank C1–C2 and are apart everywhere else,
and no edge is as short as the clearance (which would force tiny elements).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from workflow.errors import GeometryError

#: Upper bound on the estimated number of tetrahedra, so that a typo in a mesh
#: size fails at once instead of exhausting memory inside gmsh.
MAX_ELEMENTS = 2_000_000
#: Largest aspect ratio of the flank's structured cells (along x vs across).
MAX_FLANK_ASPECT = 10.0
#: Contact-node layouts of ``contact_nodes`` (the same as reduction.pairs.NODE_LAYOUTS; geometry stays light).
CONTACT_NODES = ("vertices", "all", "linear")


@dataclass(frozen=True)
class SectorParams:
    """Dimensions of one blade–disk sector (SI: m, rad) and its mesh controls.

    Disk rim
        n_sectors: sectors in the full disk; the sector angle is 2π/n_sectors.
        r_in, r_out: rim inner (clamped) and outer radii, m.
        axial_length: length of the axial dovetail slot (and the rim), m.

    Dovetail (blade root, the slot is the root plus clearances)
        neck_width: width of the blade neck, m.
        lobe_width: width of the blade root across its lobes, m.
        flank_angle: angle of the inclined bearing face below the
            circumferential (y) direction, rad; 0 would be a purely radial
            bearing, π/2 a vertical face that carries no radial load.
        flank_length: length (in the y–z plane) of the contact flank, the
            middle part of the inclined face, m.
        neck_height: depth of the top of the inclined face below r_out, m.
        lobe_height: height of the vertical lobe side below the inclined face, m.
        clearance: gap between root and slot away from the flanks (slot
            sides, slot bottom, neck top), m.
        relief_angle: angle by which the blade's inclined face turns away
            from the disk beyond each end of the flank, rad (0 keeps it
            straight, which gives flat tetrahedra along the flank's edges).

    Shank and platform
        shank_height: radial gap between r_out and the platform underside, m
            (the neck continues through it as the shank).
        platform_width: circumferential width of the platform, m.
        platform_thickness: radial thickness of the platform, m.

    Airfoil (a cambered, twisted thin plate; chord centred at x = L/2, y = 0)
        span: radial length above the platform, m.
        chord: chord length, m.
        thickness: plate thickness, m.
        camber: maximum camber height / chord (parabolic camber line, convex
            towards +y: +y is the extrados/suction side).
        stagger: angle of the root chord from the x axis, rad.
        twist: tip stagger minus root stagger, rad (linear along the span).

    Mesh
        h_blade, h_disk, h_airfoil: target element sizes in the blade root
            and platform, the disk, and the airfoil, m.
        h_flank: element size in the solid next to the contact flanks, m:
            within flank_length/2 of them, growing beyond to the body's size
            (geometry.meshing.GROWTH); 0 leaves h_blade and h_disk there. The
            worn state follows the solid's mesh next to the flanks as much as
            the contact grid (docs/contact-layout.md). Far below the flank
            cells' size it leaves slivers on them (gmsh's check refuses 1.5 mm
            on 4 × 2 vertices; 1–1.5 mm meshes grids of 8 × 9 and finer).
        nodes_along: contact vertices per flank along x (leading → trailing).
        nodes_across: contact vertices per flank across the flank.
        contact_nodes: which flank nodes are contact nodes: "vertices" (the
            nodes_along × nodes_across corner nodes, midside nodes free),
            "all" (vertices and midside nodes of the quadratic facets,
            (2·nodes_along − 1)(2·nodes_across − 1) per flank, with a linear
            contact layer) or "linear" (the vertices, every flank midside
            node tied to its edge's midpoint: a linear contact surface, the
            paper's node count without interpenetration between vertices);
            reduction/pairs.py, docs/contact-layout.md.
        flank_grading: gmsh's "Bump" coefficient of the contact vertices
            across each flank, in (0, 1]: 1 spaces them evenly; below 1
            they crowd towards both long edges, where the flanks bear under
            the preload (docs/contact-layout.md), the end cells about
            √flank_grading of the even spacing (0.2: 0.45×), the middle ones
            wider (with 2 or 3 vertices across, the spacing stays even).
        element_order: 1 or 2 (Lagrange tetrahedra).

    Cyclic symmetry
        cyclic: mesh the disk's two cut faces (the planes through the x
            axis at ±π/n_sectors) as periodic under the rotation by
            2π/n_sectors about x, tagged cyclic_low (+y face) and
            cyclic_high (−y face = R·low); false keeps the paper's sector
            (docs/cyclic.md).
    """

    n_sectors: int = 47
    r_in: float = 0.200
    r_out: float = 0.240
    axial_length: float = 0.040

    neck_width: float = 0.008
    lobe_width: float = 0.018
    flank_angle: float = math.radians(45.0)
    flank_length: float = 0.005
    neck_height: float = 0.005
    lobe_height: float = 0.003
    clearance: float = 0.0003
    relief_angle: float = math.radians(30.0)

    shank_height: float = 0.006
    platform_width: float = 0.028
    platform_thickness: float = 0.003

    span: float = 0.12
    chord: float = 0.04
    thickness: float = 0.003
    camber: float = 0.05
    stagger: float = math.radians(25.0)
    twist: float = math.radians(20.0)

    h_blade: float = 0.004
    h_disk: float = 0.007
    h_airfoil: float = 0.006
    h_flank: float = 0.0
    nodes_along: int = 4
    nodes_across: int = 2
    flank_grading: float = 1.0
    element_order: int = 2
    contact_nodes: str = "vertices"
    cyclic: bool = False

    # ---- derived quantities (all in the y–z plane, half profile y ≥ 0) ----

    @property
    def sector_angle(self) -> float:
        """Full angle of the sector, rad."""
        return 2.0 * math.pi / self.n_sectors

    def to_dict(self) -> dict:
        """Plain dict of the parameters (JSON-serialisable)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def check_params(p: SectorParams) -> None:
    """Raise :class:`GeometryError` naming the first parameter that cannot
    make a valid sector; return None if the sector can be built."""
    _check_types(p)
    _check_dovetail(p)
    _check_fit(p)
    _check_airfoil(p)
    _check_mesh_size(p)


def _fail(name: str, why: str) -> None:
    raise GeometryError(f"geometry.{name}: {why}")


def _check_types(p: SectorParams) -> None:
    for f in fields(p):
        v = getattr(p, f.name)
        if f.type in ("bool", bool):
            if not isinstance(v, bool):
                _fail(f.name, f"must be true or false, got {v!r}")
        elif f.type in ("int", int):
            if isinstance(v, bool) or not isinstance(v, int):
                _fail(f.name, f"must be an integer, got {v!r}")
        elif f.type in ("str", str):
            if v not in CONTACT_NODES:
                _fail(f.name, f"must be one of {', '.join(map(repr, CONTACT_NODES))}, got {v!r}")
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                _fail(f.name, f"must be a finite number, got {v!r}")
    if p.n_sectors < 3:
        _fail("n_sectors", f"must be ≥ 3, got {p.n_sectors}")
    for name in ("r_in", "r_out", "axial_length", "neck_width", "lobe_width", "flank_length",
                 "neck_height", "lobe_height", "clearance", "shank_height", "platform_width",
                 "platform_thickness", "span", "chord", "thickness", "h_blade", "h_disk", "h_airfoil"):
        if getattr(p, name) <= 0:
            _fail(name, f"must be > 0, got {getattr(p, name)!r}")
    if p.h_flank < 0 or p.h_flank > min(p.h_blade, p.h_disk):
        _fail("h_flank", f"must be 0 (no local size) or in (0, min(h_blade, h_disk) = "
                         f"{min(p.h_blade, p.h_disk)}], got {p.h_flank!r}")
    if p.nodes_along < 2:
        _fail("nodes_along", f"must be ≥ 2, got {p.nodes_along}")
    if p.nodes_across < 2:
        _fail("nodes_across", f"must be ≥ 2, got {p.nodes_across}")
    if not 0.0 < p.flank_grading <= 1.0:
        _fail("flank_grading", f"must be in (0, 1] (1: evenly spaced across the flank), got {p.flank_grading!r}")
    if p.element_order not in (1, 2):
        _fail("element_order", f"must be 1 or 2, got {p.element_order}")
    if p.contact_nodes != "vertices" and p.element_order != 2:
        _fail("contact_nodes", f"{p.contact_nodes!r} needs midside nodes (element_order = 2)")
    if p.contact_nodes == "linear" and p.cyclic:
        _fail("contact_nodes", "'linear' (tied midside nodes) is not implemented with cyclic = true; "
                               "use 'vertices' or 'all'")
    # The flank's structured cells are faces of tetrahedra: very elongated
    # cells leave only slivers to attach to them.
    da, dc = p.axial_length / (p.nodes_along - 1), p.flank_length / (p.nodes_across - 1)
    dc *= math.sqrt(p.flank_grading) if p.nodes_across > 3 else 1.0   # the Bump's end cells (symmetric: ≤ 3 stay even)
    if max(da, dc) / min(da, dc) > MAX_FLANK_ASPECT:
        # either key can be at fault: the one the user changed is named first (the scene's blame)
        name = "nodes_along and geometry.nodes_across"
        _fail(name, f"flank cells would be {1e3 * da:.3g} mm (along) × {1e3 * dc:.3g} mm (across), "
                    f"aspect {max(da, dc) / min(da, dc):.3g} > {MAX_FLANK_ASPECT}; the tetrahedra on "
                    f"them would be slivers: balance nodes_along and nodes_across")


def _check_dovetail(p: SectorParams) -> None:
    from geometry.profile import Dovetail

    lo, hi = math.radians(10.0), math.radians(80.0)
    if not lo <= p.flank_angle <= hi:
        _fail("flank_angle", f"must be between 10° and 80° (in radians), got {p.flank_angle!r} rad "
                             f"= {math.degrees(p.flank_angle):.1f}°")
    if not 0.0 <= p.relief_angle <= math.radians(45.0) or p.flank_angle + p.relief_angle >= math.radians(85.0):
        _fail("relief_angle", f"must be between 0 and 45° (in radians) with flank_angle + relief_angle "
                              f"< 85°, got {p.relief_angle!r} rad = {math.degrees(p.relief_angle):.1f}°")
    if p.r_in >= p.r_out:
        _fail("r_in", f"must be < r_out = {p.r_out}, got {p.r_in}")
    if p.lobe_width <= p.neck_width:
        _fail("lobe_width", f"must exceed neck_width = {p.neck_width} (else there is no dovetail), "
                            f"got {p.lobe_width}")
    if p.clearance >= 0.5 * p.neck_width:
        _fail("clearance", f"must be < neck_width/2 = {0.5 * p.neck_width}, got {p.clearance}")
    d = Dovetail.from_params(p)
    if p.r_out - p.neck_height >= d.T[1]:
        _fail("neck_height", f"{p.neck_height} puts the inclined face above the rim top next to the "
                             f"neck; it must exceed {p.r_out - d.T[1]:.3g} m")
    if d.flank_length > d.inclined_length:
        _fail("flank_length", f"{p.flank_length} is longer than the inclined face "
                              f"({d.inclined_length:.6g} m, set by lobe_width, neck_width, flank_angle)")
    # At C1 the disk's neck face must leave the flank line on the open side of
    # the blade's neck: the relief must be wider (in y) than the clearance.
    if d.relief * math.cos(p.flank_angle) <= p.clearance:
        _fail("flank_length", f"{p.flank_length} leaves no room for the neck clearance: the inclined "
                              f"face ({d.inclined_length:.6g} m) must exceed flank_length by more than "
                              f"2·clearance/cos(flank_angle) = {2 * p.clearance / math.cos(p.flank_angle):.6g} m")
    if d.z_slot_bottom <= p.r_in:
        _fail("r_in", f"the slot bottom (r = {d.z_slot_bottom:.6g} m) is not above the rim inner radius "
                      f"{p.r_in}; make the rim deeper or the dovetail shallower")


def _check_fit(p: SectorParams) -> None:
    """The slot and the platform must lie inside the sector's wedge."""
    from geometry.profile import Dovetail

    d = Dovetail.from_params(p)
    half = 0.5 * p.sector_angle
    # The slot's widest, lowest corner must leave disk material (a post) to
    # the sector's side plane.
    if math.atan2(d.y_slot_side, d.z_slot_bottom) >= half:
        _fail("lobe_width", f"the slot ({2 * d.y_slot_side:.6g} m wide at r = {d.z_slot_bottom:.6g} m) "
                            f"is wider than the sector (n_sectors = {p.n_sectors})")
    if p.platform_width <= p.neck_width:
        _fail("platform_width", f"must exceed neck_width = {p.neck_width}, got {p.platform_width}")
    if math.atan2(0.5 * p.platform_width, d.z_platform_bottom) >= half:
        _fail("platform_width", f"the blade ({p.platform_width} m) is wider than the sector "
                                f"({2 * d.z_platform_bottom * math.tan(half):.6g} m at the platform, "
                                f"n_sectors = {p.n_sectors})")


def _check_airfoil(p: SectorParams) -> None:
    from geometry.airfoil import Airfoil

    if p.thickness >= 0.25 * p.chord:
        _fail("thickness", f"must be < chord/4 = {0.25 * p.chord} for a thin plate, got {p.thickness}")
    if not 0.0 <= p.camber <= 0.2:
        _fail("camber", f"must be between 0 and 0.2 (camber height / chord), got {p.camber}")
    if abs(p.stagger) >= math.radians(80.0):
        _fail("stagger", f"must be within ±80° (in radians), got {p.stagger!r}")
    if abs(p.twist) >= math.radians(80.0):
        _fail("twist", f"must be within ±80° (in radians), got {p.twist!r}")
    af = Airfoil.from_params(p)
    pts = np.vstack(af.section_sides(af.z_root) + af.section_sides(af.z_platform))
    x, y = pts[:, 0], pts[:, 1]
    if x.min() < 0.0 or x.max() > p.axial_length or abs(y).max() > 0.5 * p.platform_width:
        _fail("chord", f"the airfoil root section (chord {p.chord} m at stagger "
                       f"{math.degrees(p.stagger):.1f}°) does not fit on the platform "
                       f"(axial_length {p.axial_length} m × platform_width {p.platform_width} m)")


def flank_zone(p: SectorParams) -> float:
    """Distance from the flanks [m] within which the solid is meshed at ``h_flank``: half the
    flank's width, where the contact's stresses are still a large share of their surface value."""
    return 0.5 * p.flank_length


def estimate_elements(p: SectorParams) -> dict[str, float]:
    """Estimated tetrahedra per region, keyed by the size key that sets it
    (within ~10 % of gmsh's count on the quick sector: 2012 vs 1840)."""
    from geometry.profile import Dovetail

    d = Dovetail.from_params(p)
    # A regular tetrahedron of edge h has volume h³/(6√2); Delaunay meshes
    # have ~1.5× more, smaller elements than that bound.
    per = lambda vol, h: 1.5 * vol / (h ** 3 / (6 * math.sqrt(2)))
    out = {
        "h_disk": per(d.disk_area() * p.axial_length, p.h_disk),
        "h_blade": per(d.root_area() * p.axial_length, p.h_blade),
        # A thin plate still needs ≥ 1 element through its thickness.
        "h_airfoil": per(p.span * p.chord * max(p.thickness, p.h_airfoil), p.h_airfoil),
    }
    if p.h_flank > 0:
        # Both sides of two flanks, each a slab flank_zone deep beyond its width.
        zone = flank_zone(p)
        out["h_flank"] = per(2 * 2 * zone * (p.flank_length + 2 * zone) * p.axial_length, p.h_flank)
    return out


#: Keys that set each region's volume, named with its size key when the mesh is too big.
_VOLUME_KEYS = {"h_disk": "axial_length", "h_blade": "axial_length", "h_airfoil": "span, chord",
                "h_flank": "axial_length, flank_length"}


def _check_mesh_size(p: SectorParams) -> None:
    """Refuse a sector whose estimated tetrahedron count exceeds MAX_ELEMENTS (in total)."""
    regions = estimate_elements(p)
    total = sum(regions.values())
    if total > MAX_ELEMENTS:
        name = max(regions, key=regions.get)
        _fail(name, f"{getattr(p, name)} m would make ~{regions[name]:.3g} elements (~{total:.3g} in all; limit "
                    f"{MAX_ELEMENTS}); raise {name} or reduce {_VOLUME_KEYS[name]}")
