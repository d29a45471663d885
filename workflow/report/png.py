"""One way to write a matplotlib figure: a PNG at 110 dpi, atomically (``workflow.io``)."""
from __future__ import annotations

from pathlib import Path


def save_png(fig, path: Path) -> Path:
    """Write ``fig`` to ``path`` (.png), creating its folder; the caller closes ``fig``."""
    from workflow.io import atomic_path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    return path


def write_figure(fig, path: Path) -> Path:
    """Lay out ``fig``, write it (:func:`save_png`) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = save_png(fig, path)
    plt.close(fig)
    return path


def finish_axes(ax, xlabel: str, ylabel: str, title: str = "", title_size: float | None = None,
                which: str = "major") -> None:
    """Labels, title, a light grid (``which = "both"`` for log–log plots) and a small
    legend: the look of every line plot of the report and the benchmarks."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, **({"fontsize": title_size} if title_size else {}))
    ax.grid(True, which=which, alpha=0.3)
    if ax.get_legend_handles_labels()[1]:      # an image or a bar chart may have nothing to name
        ax.legend(fontsize=8)
