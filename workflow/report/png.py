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
