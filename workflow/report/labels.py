"""Text labels beside scattered points that neither overlap each other nor leave the axes.

:func:`place_labels` is a small greedy placer (the idea of adjustText, without the
dependency): each label tries positions on rings of growing radius around its point,
16 directions a ring, and takes the first one whose box overlaps no label placed
before it, no marker, no box to avoid (the legend) and lies inside the axes; labels
with the most crowded points go first. A label put further than ``leader_px`` from its
point gets a thin leader line. Labels are measured and placed in the display pixels of
the figure as it stands, then fixed in data coordinates: the caller sets the axis limits
and margins (and the legend) first — a later change moves the points under the labels.
"""
from __future__ import annotations

import math

import numpy as np

#: ring radii (px at the figure's dpi) tried around each point, nearest first
RADII = (4.0, 9.0, 15.0, 23.0, 33.0, 46.0, 62.0, 82.0, 108.0, 140.0, 180.0, 230.0)
#: directions tried on each ring (first: up-right, the usual place of a label)
ANGLES = tuple(math.radians(a) for a in (30, 150, -30, -150, 60, 120, -60, -120, 0, 180, 90, -90,
                                         15, 165, -15, -165))
#: gap (px) kept between two boxes and between a box and the axes' edge
PAD = 2.0


def _overlap(a, b, pad: float = 0.0) -> bool:
    """Do boxes ``a``, ``b`` = (x0, y0, x1, y1) overlap (with ``pad`` px between them)?"""
    return a[0] < b[2] + pad and b[0] < a[2] + pad and a[1] < b[3] + pad and b[1] < a[3] + pad


def _crosses(p, q, box) -> bool:
    """Does the segment p–q pass through ``box`` (Liang–Barsky clipping)?"""
    t0, t1 = 0.0, 1.0
    dx, dy = q[0] - p[0], q[1] - p[1]
    for d, lo, hi in ((dx, box[0] - p[0], box[2] - p[0]), (dy, box[1] - p[1], box[3] - p[1])):
        if d == 0.0:
            if lo > 0 or hi < 0:
                return False
            continue
        a, b = sorted((lo / d, hi / d))
        t0, t1 = max(t0, a), min(t1, b)
        if t0 > t1:
            return False
    return True


def _anchor(box, p):
    """The point of ``box`` nearest to ``p`` (where a leader line ends)."""
    return (min(max(p[0], box[0]), box[2]), min(max(p[1], box[1]), box[3]))


def place_labels(ax, xy, texts, *, fontsize: float = 7.0, marker_px: float = 8.0, avoid=(), leader_px: float = 10.0,
                 **text_kw) -> list:
    """Label each point ``xy[i]`` (data coordinates) of ``ax`` with ``texts[i]``, no two labels
    overlapping and every label inside the axes; returns the Text artists in the order given.

    ``marker_px``: the markers' size in px (their boxes are avoided too); ``avoid``: more
    display-space boxes (x0, y0, x1, y1) to keep clear of, e.g. the legend's extent; a label
    placed more than ``leader_px`` from its point is joined to it by a thin line. Where no
    position on any ring is free, the label goes where it overlaps least (the rings reach
    230 px: only a very crowded figure gets there)."""
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    pts = ax.transData.transform(np.asarray(xy, dtype=float).reshape(-1, 2))
    frame = ax.get_window_extent(renderer)
    inner = (frame.x0 + PAD, frame.y0 + PAD, frame.x1 - PAD, frame.y1 - PAD)
    half = 0.5 * marker_px
    markers = [(x - half, y - half, x + half, y + half) for x, y in pts]
    artists, sizes = [], []
    for t in texts:  # measure each label as drawn; it is moved once placed
        a = ax.text(0.5, 0.5, t, transform=ax.transAxes, fontsize=fontsize, ha="center", va="center", **text_kw)
        e = a.get_window_extent(renderer)
        sizes.append((e.width, e.height))
        artists.append(a)
    # the most crowded points first: they have the fewest free places
    scale = 60.0
    crowd = [sum(math.exp(-((p - q) ** 2).sum() / scale ** 2) for q in pts) for p in pts]
    order = sorted(range(len(pts)), key=lambda i: -crowd[i])
    placed: list[tuple] = []
    leaders: list[tuple] = []
    where = [None] * len(pts)
    for i in order:
        p, (w, h) = pts[i], sizes[i]
        best, best_cost = None, math.inf
        for r in RADII:
            for ang in ANGLES:
                c, s = math.cos(ang), math.sin(ang)
                cx, cy = p[0] + (r + half + 0.5 * w) * c, p[1] + (r + half + 0.5 * h) * s
                box = (cx - 0.5 * w, cy - 0.5 * h, cx + 0.5 * w, cy + 0.5 * h)
                if not (box[0] >= inner[0] and box[1] >= inner[1] and box[2] <= inner[2] and box[3] <= inner[3]):
                    continue
                hits = sum(_overlap(box, b, PAD) for b in placed) + sum(_overlap(box, m) for m in markers) \
                    + sum(_overlap(box, b, PAD) for b in avoid)
                end = _anchor(box, p)
                if math.hypot(end[0] - p[0], end[1] - p[1]) > leader_px + half:
                    # its leader should not cut through a label, nor a label through a leader
                    hits_soft = sum(_crosses(p, end, b) for b in placed) + sum(_crosses(a, b_, box)
                                                                               for a, b_ in leaders)
                else:
                    hits_soft = sum(_crosses(a, b_, box) for a, b_ in leaders)
                cost = 1e6 * hits + 1e3 * hits_soft + r
                if cost < best_cost:
                    best, best_cost = box, cost
            if best_cost < 1e3:  # a free place on this ring: nearer rings were full
                break
        if best is None:  # nothing inside the axes at all (a label wider than the axes): at the point
            best = (p[0] - 0.5 * w, p[1] - 0.5 * h, p[0] + 0.5 * w, p[1] + 0.5 * h)
        placed.append(best)
        where[i] = best
        end = _anchor(best, p)
        if math.hypot(end[0] - p[0], end[1] - p[1]) > leader_px + half:
            leaders.append((tuple(p), end))
    to_data = ax.transData.inverted()
    for i, a in enumerate(artists):
        box, p = where[i], pts[i]
        a.set_transform(ax.transData)
        a.set_position(tuple(to_data.transform((0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])))))
        end = _anchor(box, p)
        if math.hypot(end[0] - p[0], end[1] - p[1]) > leader_px + half:
            _leader(ax, p, end)
    return artists


def _leader(ax, p, q) -> None:
    """A thin grey line from point ``p`` to ``q`` (display px), below the markers and labels."""
    from matplotlib.lines import Line2D

    inv = ax.transData.inverted()
    (x0, y0), (x1, y1) = inv.transform(p), inv.transform(q)
    ax.add_line(Line2D([x0, x1], [y0, y1], color="0.55", lw=0.6, zorder=1.5))
