"""Fake stage modules for the pipeline and CLI tests (no FE code needed).

Each fake has the real stage's NAME/SECTIONS/NEEDS/PRODUCES shape, checks
that its inputs exist, writes a small file (plus a PNG and a CSV for the
report), appends its name to the file ``$FAKE_TRACE`` (what ran, in order),
keeps its first half in the pipeline's progress folder (``<stage>.resumed`` beside
``$FAKE_TRACE`` when a later run found it there), and can be told to crash half-way
through with ``$FAKE_CRASH=<stage>:interrupt``
(KeyboardInterrupt) or ``<stage>:exit`` (``os._exit``: no clean-up at all).
"""
from __future__ import annotations

import sys
import uuid
from pathlib import Path

import pytest

# name: (SECTIONS, NEEDS, PRODUCES) — the dependency shape of the real stages.
STAGES = {
    "geometry": (("geometry",), (), ("mesh",)),
    "assembly": (("material", "rotation", "damping", "excitation"), ("mesh",), ("bundle",)),
    "modes": (("modes",), ("bundle",), ("modes",)),
    "reduction": (("reduction",), ("bundle",), ("reduced",)),
    "reduction_check": (("reduction",), ("bundle", "reduced"), ("reduction_check",)),
    "hb": (("contact", "hb", "sweep"), ("reduced",), ("frf",)),
    "wear": (("contact", "hb", "wear", "pseudotime"), ("reduced", "frf"), ("wear",)),
    "remap": (("remap",), ("wear", "bundle"), ("wear_map",)),
    "extreme": (("extreme",), ("reduced",), ("extreme",)),
}

# The smallest valid PNG (1×1, grey).
PNG = bytes.fromhex("89504e470d0a1a0a0000000d4948445200000001000000010800000000"
                    "3a7e9b550000000a4944415478da6360000000020001e221bc330000000049454e44ae426082")

TEMPLATE = '''\
import os
from pathlib import Path

NAME = {name!r}
SECTIONS = {sections!r}
NEEDS = {needs!r}
PRODUCES = {produces!r}
PNG = {png!r}


def run(scene, inputs, out, log):
    for need in NEEDS:
        assert (Path(inputs[need]) / "data.txt").is_file(), need
    with open(os.environ["FAKE_TRACE"], "a") as fh:
        fh.write(NAME + "\\n")
    (out / "part1.txt").write_text("first half")
    from workflow import progress
    store = progress.current()          # the first half kept for a run after an interruption
    if store is not None:
        if store.get("first-half") == {{"stage": NAME}}:
            (Path(os.environ["FAKE_TRACE"]).parent / (NAME + ".resumed")).write_text("")
        store.put("first-half", {{"stage": NAME}})
    crash = os.environ.get("FAKE_CRASH", "")
    if crash == NAME + ":interrupt":
        raise KeyboardInterrupt
    if crash == NAME + ":exit":
        os._exit(9)
    if crash.startswith(NAME + ":sigdfl"):
        # what the geometry stage does (gmsh's import sets SIGINT to SIG_DFL); then work in
        # Python (loop) or inside a C call (sleep)
        import time
        import gmsh  # noqa: F401
        (Path(os.environ["FAKE_TRACE"]).parent / "busy").write_text("")
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            if crash.endswith("loop"):
                sum(range(1000))
            else:
                time.sleep(60)
    for _ in log.progress(range(20), label="fake work"):
        pass
    values = {{s: repr(scene[s]) for s in SECTIONS}}
    (out / "data.txt").write_text(NAME + "\\n" + repr(values))
    (out / "figure.png").write_bytes(PNG)
    (out / "table.csv").write_text("i,value\\n" + "".join(f"{{i}},{{i * i}}\\n" for i in range(30)))
    summary = {{"name": NAME, "contact_pairs": 8, "files": ["data.txt", "figure.png", "table.csv"]}}
    if os.environ.get("FAKE_UNCONVERGED") == NAME:
        summary["unconverged"] = [NAME + ": 2/15 frequencies did not converge (max iterations)"]
    if os.environ.get("FAKE_WARNING") == NAME:
        summary["warnings"] = ["Nh-check: the peak moves by 5.00e-03 (> 0.001); raise hb.harmonics"]
    return summary
'''


class Fakes:
    """A package of fake stages on sys.path, registered in workflow.stages."""

    def __init__(self, root: Path):
        self.pkg = "fakestages_" + uuid.uuid4().hex[:8]
        self.root = root
        self.trace = root / "trace.txt"
        d = root / self.pkg
        d.mkdir(parents=True)
        (d / "__init__.py").write_text("")
        for name, (sections, needs, produces) in STAGES.items():
            (d / f"{name}.py").write_text(TEMPLATE.format(name=name, sections=sections, needs=needs,
                                                          produces=produces, png=PNG))

    def modules(self) -> dict[str, str]:
        return {name: f"{self.pkg}.{name}" for name in STAGES}

    def ran(self) -> list[str]:
        """Stages that ran since the last call (and reset)."""
        if not self.trace.exists():
            return []
        names = self.trace.read_text().split()
        self.trace.unlink()
        return names

    def driver(self) -> str:
        """Python source that registers the fakes and runs ``workflow.cli.main(sys.argv[1:])``."""
        return (f"import sys\nsys.path.insert(0, {str(self.root)!r})\n"
                "from workflow import stages, pipeline\n"
                f"stages.MODULES.update({self.modules()!r})\n"
                # Other engineers edit the packages while tests run: pin the code version.
                "pipeline.code_version = lambda: 'test'\n"
                "from workflow.cli import main\nsys.exit(main(sys.argv[1:]))\n")


def install(tmp_path: Path, monkeypatch) -> Fakes:
    """Create the fakes under ``tmp_path`` and register them for this test."""
    from workflow import pipeline, stages

    fakes = Fakes(tmp_path / "fakes")
    monkeypatch.syspath_prepend(str(fakes.root))
    for name, mod in fakes.modules().items():
        monkeypatch.setitem(stages.MODULES, name, mod)
    monkeypatch.setattr(pipeline, "code_version", lambda: "test")
    monkeypatch.setenv("FAKE_TRACE", str(fakes.trace))
    monkeypatch.delenv("FAKE_CRASH", raising=False)
    monkeypatch.delenv("FAKE_UNCONVERGED", raising=False)
    monkeypatch.delenv("FAKE_WARNING", raising=False)
    monkeypatch.delenv("BLADEWEAR_CACHE", raising=False)
    return fakes


def write_scene(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def loaded(pkg: str) -> list[str]:
    return sorted(m.rsplit(".", 1)[1] for m in sys.modules if m.startswith(pkg + "."))


@pytest.fixture
def fakes(tmp_path, monkeypatch):
    """Fake stage modules registered in place of the real ones."""
    return install(tmp_path, monkeypatch)


def run(capsys, *argv):
    """``bladewear argv…`` in-process: ``(exit code, stdout, stderr)``."""
    from workflow.cli import main

    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err
