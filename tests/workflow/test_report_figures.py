"""The report's FRF error-against-run-time figure: its per-variant labels are readable —
no two overlap, none leaves the axes — however the variants cluster (issue #46)."""
from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from workflow.engine.studies.variants import Variant
from workflow.report.frf import error_figure
from workflow.report.labels import place_labels


def _runs(points):
    """Stand-ins for the engine's sweep results: what :func:`error_figure` reads."""
    return [SimpleNamespace(variant=Variant(m, nh, nit), total_seconds=t, error=e) for (m, nh, nit), t, e in points]


def _boxes(fig, texts):
    fig.canvas.draw()     # as saved: every artist laid out
    r = fig.canvas.get_renderer()
    return [t.get_window_extent(r) for t in texts]


def _assert_readable(fig, texts):
    boxes = _boxes(fig, texts)
    frame = fig.axes[0].get_window_extent(fig.canvas.get_renderer())
    for b in boxes:       # inside the axes (so inside the figure)
        assert frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1, (b, frame)
    for (i, a), (j, b) in itertools.combinations(enumerate(boxes), 2):
        assert not a.overlaps(b), (texts[i].get_text(), texts[j].get_text(), a, b)


#: eight variants with near-equal error and run time: every label wants the same place
CLUSTER = [(("hbm", 17, 35), 9.6, 1.68e-3), (("tcm", 17, 35), 9.4, 1.68e-3), (("hdhb", 17, 35), 9.5, 1.69e-3),
           (("hbm", 17, 105), 9.7, 1.66e-3), (("tcm", 17, 105), 9.55, 1.70e-3), (("hbm", 7, 15), 9.45, 1.67e-3),
           (("tcm", 7, 15), 9.65, 1.675e-3), (("hdhb", 7, 15), 9.5, 1.685e-3)]


@pytest.mark.parametrize("uncertainty", [None, 1.5e-3])
def test_error_figure_labels_of_a_tight_cluster_do_not_overlap(uncertainty):
    import matplotlib.pyplot as plt

    fig, texts = error_figure(_runs(CLUSTER), "HBM-25 nit=128", uncertainty)
    try:
        assert len(texts) == len(CLUSTER)
        assert sorted(t.get_text() for t in texts) == sorted(f"{m.upper()}-{nh}/{nit}" for (m, nh, nit), *_ in CLUSTER)
        _assert_readable(fig, texts)
        leg = fig.axes[0].get_legend().get_window_extent(fig.canvas.get_renderer())
        assert not any(b.overlaps(leg) for b in _boxes(fig, texts))
        assert fig.axes[0].get_xscale() == fig.axes[0].get_yscale() == "log"
    finally:
        plt.close(fig)


def test_error_figure_labels_of_the_paper_variants_at_the_edges_stay_inside():
    # paper-frf's 20 variants (times and errors of a run), the dearest and the cheapest at the
    # axes' edges, where the old labels ran out of the figure
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(46)
    variants = [(m, nh, nit) for m in ("hbm", "tcm") for nh in (1, 3, 7, 17) for nit in (105, 2 * nh + 1)]
    variants += [("hdhb", nh, 2 * nh + 1) for nh in (1, 3, 7, 17)]
    pts = [(v, (0.3 + 0.05 * v[1]) * rng.uniform(0.9, 1.1), 0.4 * v[1] ** -2.0 * rng.uniform(0.8, 1.2))
           for v in variants]
    fig, texts = error_figure(_runs(pts), "HBM-31 nit=160", 3.2e-4)
    try:
        assert len(texts) == 20
        _assert_readable(fig, texts)
    finally:
        plt.close(fig)


def test_place_labels_on_one_point_repeated():
    # the worst cluster: eight labels for one and the same point
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.5), dpi=110)
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.0)
    try:
        texts = place_labels(ax, [(0.5, 0.5)] * 8, [f"variant {i}" for i in range(8)])
        _assert_readable(fig, texts)
    finally:
        plt.close(fig)
