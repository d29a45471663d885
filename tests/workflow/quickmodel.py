"""The quick scene's reduced model (16 pairs, 110 DOFs), built by the pipeline into a folder:
for the slow tests that need the real sector without its HB or wear."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def quick_reduced(tmp: Path):
    """``bladewear run quick`` up to the reduction (≈ 10 s) in ``tmp``; the ReducedModel."""
    from workflow.engine.model import ReducedModel

    out = Path(tmp) / "quick"
    r = subprocess.run([str(Path(sys.executable).parent / "bladewear"), "run", "quick", "--out", str(out),
                        "--cache", str(Path(tmp) / "cache"), "--quiet", "--set", 'run.outputs=["reduced"]'],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return ReducedModel.load(out / "reduction" / "reduced.npz")
