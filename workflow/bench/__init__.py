"""Benchmarks and convergence studies (scripts: python -m workflow.bench.<name>)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def run_to(scene: str, product: str, folder: Path) -> Path:
    """``bladewear run scene`` up to ``product`` (cached like any run) into ``folder``; returns it."""
    subprocess.run([str(Path(sys.executable).parent / "bladewear"), "run", scene, "--set",
                    f'run.outputs=["{product}"]', "--out", str(folder), "--quiet"], check=True)
    return Path(folder)
