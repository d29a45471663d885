"""The geometry → assembly → modes stages on the default sector (contracts §8)."""
import json

import pytest

from workflow import params as P


class _Log:
    def __init__(self):
        self.lines = []

    def info(self, msg):
        self.lines.append(msg)

    def progress(self, iterable, total=None, label=""):
        return iterable

    def child(self, name):
        return self


@pytest.fixture(scope="module")
def scene():
    from geometry.params import SectorParams

    return {"geometry": SectorParams(), "material": P.Material(), "rotation": P.Rotation(speed_rpm=10000.0),
            "damping": P.Damping(), "excitation": P.Excitation(), "modes": P.Modes(count=4)}


def test_stages_chain(scene, tmp_path):
    from workflow.stages import assembly, geometry, load, modes

    for m in (geometry, assembly, modes):
        assert load(m.NAME) is m
    log = _Log()
    g = geometry.run(scene, {}, tmp_path / "geometry", log)
    assert g["contact_pairs"] == 2 * scene["geometry"].nodes_along * scene["geometry"].nodes_across
    assert g["pair_distance_max"] < 1e-12
    a = assembly.run(scene, {"mesh": tmp_path / "geometry"}, tmp_path / "assembly", log)
    assert a["n_pairs"] == g["contact_pairs"]
    assert a["mass_kg"] == pytest.approx(scene["material"].density * a["volume_m3"], rel=1e-6)  # curved airfoil
    assert (tmp_path / "assembly" / a["bundle"] / "mesh.xdmf").is_file()
    m = modes.run(scene, {"bundle": tmp_path / "assembly"}, tmp_path / "modes", log)
    f = m["eigenfrequencies_hz"]
    assert len(f) == 4 and 0 < f[0] < f[1] and f[0] == pytest.approx(a["first_tied_hz"], rel=1e-6)
    json.dumps([g, a, m])
    # A user's bundle folder (the [model] bundle product) works too.
    m2 = modes.run(scene, {"bundle": tmp_path / "assembly" / "model"}, tmp_path / "modes2", log)
    assert m2["eigenfrequencies_hz"] == pytest.approx(f, rel=1e-8)


def test_assembly_names_missing_geometry(tmp_path, scene):
    from workflow.errors import GeometryError
    from workflow.stages import assembly

    with pytest.raises(GeometryError, match="sector.msh"):
        assembly.run(scene, {"mesh": tmp_path}, tmp_path / "out", _Log())
