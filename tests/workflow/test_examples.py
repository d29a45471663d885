"""Every script in examples/ runs and says what it computed (scikit-fem's rule: examples are tests)."""
from __future__ import annotations

import runpy
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.py"))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(path, capsys):
    runpy.run_path(str(path), run_name="__main__")
    out = capsys.readouterr().out
    assert "converged" in out and "steady = True" in out, out
    # the friction-damped peak lies below the tied linear one (friction only damps)
    peak, tied = (float(out.split(k)[1].split()[0].rstrip(")").rstrip(";")) for k in (" Hz, ", "(tied "))
    assert 0 < peak < tied
    # an answer the Nh-check finds unconverged is never printed without its warning
    if "change at 1.5×Nh" in out and float(out.split("change at 1.5×Nh ")[1].split()[0]) > 1e-3:
        assert "check: Nh-check" in out, out
