"""Shared meshes and bundles for the reduction tests (built once per session)."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))  # tests/reduction/meshes.py

TI = dict(young=110e9, poisson=0.33, density=4430.0)


@pytest.fixture(scope="session")
def dovetail(tmp_path_factory):
    """(msh path, geometry info) of the two-body test dovetail (P2, ~9k DOFs)."""
    import meshes

    path = tmp_path_factory.mktemp("dovetail") / "dovetail.msh"
    info = meshes.dovetail_msh(path, h=0.004)
    return path, info


@pytest.fixture(scope="session")
def dovetail_mesh(dovetail):
    from reduction import dolfinx_compat as dc

    return dc.read_msh(dovetail[0])


@pytest.fixture(scope="session")
def rotating_bundle(dovetail, tmp_path_factory):
    """The dovetail assembled at 10000 rpm with modal damping, written and read back."""
    from reduction.assemble import as_section, assemble_bundle
    from reduction.bundle import read_bundle

    path, info = dovetail
    out = tmp_path_factory.mktemp("bundle") / "model"
    summary = assemble_bundle(path, info, as_section(TI), as_section(dict(speed_rpm=10000.0)),
                              as_section(dict(alpha=0.0, beta=0.0, modal_ratio=0.002)),
                              as_section(dict(amplitude=0.1, static_force=0.0)), out)
    return read_bundle(out), summary, info
