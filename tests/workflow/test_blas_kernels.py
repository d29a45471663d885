"""OpenBLAS's kernels chosen from the CPU's instruction sets (workflow.blas_kernels)."""
from __future__ import annotations

import sys

import pytest

from workflow import blas_kernels

AVX512 = "avx avx2 fma avx512f avx512cd avx512bw avx512dq avx512vl"


def cpuinfo(vendor: str, flags: str) -> str:
    cpu = f"processor\t: {{i}}\nvendor_id\t: {vendor}\nmodel\t\t: 207\nflags\t\t: fpu sse sse2 {flags}\n\n"
    return cpu.format(i=0) + cpu.format(i=1)


@pytest.mark.parametrize("vendor,flags,core", [
    ("GenuineIntel", AVX512, "SkylakeX"),                       # Sapphire/Emerald Rapids: OpenBLAS 0.3.21 says Prescott
    ("GenuineIntel", "avx avx2 fma", "Haswell"),
    ("GenuineIntel", "avx avx2 fma avx512f", "Haswell"),            # AVX-512 without the subsets SkylakeX executes
    ("GenuineIntel", "avx", None),
    ("AuthenticAMD", AVX512, None),                             # other vendors: OpenBLAS's own detection
])
def test_the_kernels_follow_the_instruction_sets(vendor, flags, core):
    assert blas_kernels.coretype(cpuinfo(vendor, flags)) == core


def test_a_choice_is_made_only_before_numpy_and_never_over_the_users(tmp_path, monkeypatch):
    path = tmp_path / "cpuinfo"
    path.write_text(cpuinfo("GenuineIntel", AVX512))
    env = {"OPENBLAS_CORETYPE": "Haswell"}
    assert blas_kernels.choose(env, str(path)) == "Haswell" and env == {"OPENBLAS_CORETYPE": "Haswell"}
    import numpy  # noqa: F401  (OpenBLAS is loaded: too late to choose)

    env = {}
    monkeypatch.setattr("workflow.engine.blas.corenames", lambda: [("libopenblas.so", "Haswell")])
    assert blas_kernels.choose(env, str(path)) is None and env == {}
    monkeypatch.setattr("workflow.engine.blas.corenames", lambda: [("libopenblas.so", "Prescott")])
    with pytest.warns(RuntimeWarning, match="OPENBLAS_CORETYPE=SkylakeX"):
        assert blas_kernels.choose(env, str(path)) is None and env == {}
    monkeypatch.delitem(sys.modules, "numpy")
    assert blas_kernels.choose(env, str(path)) == "SkylakeX" and env == {"OPENBLAS_CORETYPE": "SkylakeX"}
    assert blas_kernels.choose({}, str(tmp_path / "missing")) is None    # no /proc/cpuinfo: OpenBLAS decides


def test_the_loaded_openblas_runs_the_kernels_chosen():
    """Where a core type is in force, every OpenBLAS of this process (NumPy's, SciPy's) runs it."""
    import os

    import scipy.linalg  # noqa: F401

    from workflow.engine.blas import corenames

    chosen = os.environ.get("OPENBLAS_CORETYPE")
    cores = corenames()
    if not chosen or not cores:
        pytest.skip("no core type chosen here, or no OpenBLAS found")
    assert {core.lower() for _, core in cores} == {chosen.lower()}, cores


def test_a_run_says_which_kernels_its_blas_runs():
    """run.log's BLAS line names every loaded OpenBLAS's kernels and the core type in force."""
    import os

    from workflow.engine.blas import corenames
    from workflow.pipeline import _blas_line

    line = _blas_line()
    assert line.startswith("BLAS: OpenBLAS kernels ")
    for _, core in corenames():
        assert core in line
    if os.environ.get("OPENBLAS_CORETYPE"):
        assert f"OPENBLAS_CORETYPE={os.environ['OPENBLAS_CORETYPE']}" in line
