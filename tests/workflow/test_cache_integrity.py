"""Cache entries carry the size and SHA-256 of every file; a damaged entry is
never used (issue 18, item 2), and unconverged results finish with exit 3
(item 6). Fake stages (tests/workflow/fakestages.py): no FE code.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from fakestages import fakes, run  # noqa: F401 (fakes is a fixture)
from workflow.io import manifest, record_problem, seal_record, verify_manifest


def write_scene(tmp_path, outputs=("frf",), extra=""):
    p = tmp_path / "scene.toml"
    p.write_text(f"[run]\noutputs = {json.dumps(list(outputs))}\n{extra}")
    return p


def bw(capsys, tmp_path, scene, *more):
    return run(capsys, "run", scene, "--out", tmp_path / "out", "--cache", tmp_path / "cache", "--quiet", *more)


def entry(tmp_path, stage) -> Path:
    return (tmp_path / "out" / stage).resolve()


def test_manifest_detects_truncation_edit_and_deletion(tmp_path):
    d = tmp_path / "e"
    (d / "sub").mkdir(parents=True)
    (d / "a.csv").write_text("x,y\n1,2\n3,4\n")
    (d / "sub" / "b.npz").write_bytes(b"\x00" * 1000)
    (d / ".stage.json").write_text("{}")
    rec = manifest(d)
    assert set(rec) == {"a.csv", "sub/b.npz"}          # the record itself is not part of it
    assert rec["sub/b.npz"][0] == 1000
    assert verify_manifest(d, rec) is None
    (d / "a.csv").write_text("x,y\n1,2\n3,5\n")           # same size, other bytes
    assert "checksum" in verify_manifest(d, rec)
    (d / "a.csv").write_text("x,y\n")
    assert "bytes" in verify_manifest(d, rec)
    (d / "a.csv").unlink()
    assert "a.csv is missing" in verify_manifest(d, rec)
    assert verify_manifest(d, None) is not None


def test_a_sealed_record_reads_back_whole_and_any_edit_is_caught():
    """The record's digest is over its JSON as it reads back (NumPy numbers, NaN, nested
    summaries): unchanged it passes; one number, one key or the digest itself changed, it
    does not; a record without a digest (an older version's) is not trusted."""
    import numpy as np

    rec = seal_record({"stage": "hb", "summary": {"peak": {"hz": np.float64(212.15), "m": float("nan")},
                                                  "rows": [1, 2.5, None]}, "files": {}})
    back = json.loads(json.dumps(rec, indent=2))
    assert record_problem(back) is None
    for edit in (lambda r: r["summary"]["peak"].update(hz=213.15), lambda r: r["summary"].update(x=0),
                 lambda r: r.update(record_sha256="0" * 64), lambda r: r.pop("record_sha256")):
        bad = json.loads(json.dumps(back))
        edit(bad)
        assert record_problem(bad) is not None


@pytest.mark.parametrize("stage, damage", [
    ("hb", "truncate"),          # head -c 300 over frf.csv
    ("wear", "delete"),          # a table missing
    ("reduction", "truncate"),   # reduced.npz truncated while downstream is cached
    ("hb", "edit"),              # same size, one byte changed
    ("hb", "record"),            # .stage.json itself damaged
    ("hb", "summary"),           # .stage.json still valid JSON, a number of its summary edited
])
def test_damaged_entry_is_recomputed_with_warning(tmp_path, capsys, fakes, stage, damage):
    sc = write_scene(tmp_path, ["wear"])
    rc, _, err = bw(capsys, tmp_path, sc)
    assert rc == 0, err
    fakes.ran()
    e = entry(tmp_path, stage)
    target = e / "data.txt"
    good = target.read_bytes()
    if damage == "truncate":
        target.write_bytes(good[:5])
    elif damage == "delete":
        target.unlink()
    elif damage == "edit":
        target.write_bytes(good[:-1] + bytes([good[-1] ^ 1]))
    elif damage == "summary":
        rec = json.loads((e / ".stage.json").read_text())
        rec["summary"]["edited"] = 1.0
        (e / ".stage.json").write_text(json.dumps(rec, indent=2))
    else:
        (e / ".stage.json").write_text((e / ".stage.json").read_text()[:40])

    rc, _, err = run(capsys, "show", sc, "--out", tmp_path / "out", "--cache", tmp_path / "cache")
    assert rc == 0 and "damaged" in _

    rc, _, err = bw(capsys, tmp_path, sc)
    assert rc == 0, err
    assert fakes.ran() == [stage]                       # that stage only: its key (and downstream's) is unchanged
    log = (tmp_path / "out" / "run.log").read_text()
    assert f"warning: {stage}: cache entry" in log and "damaged" in log
    assert target.read_bytes() == good                  # the recomputed entry is whole again
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["stages"][stage] == "computed"
    # The next run trusts the repaired entry.
    rc, _, _ = bw(capsys, tmp_path, sc)
    assert rc == 0 and fakes.ran() == []


def test_entry_without_checksums_is_not_trusted(tmp_path, capsys, fakes):
    sc = write_scene(tmp_path, ["modes"])
    assert bw(capsys, tmp_path, sc)[0] == 0
    fakes.ran()
    rec_file = entry(tmp_path, "modes") / ".stage.json"
    rec = json.loads(rec_file.read_text())
    del rec["files"]
    rec_file.write_text(json.dumps(seal_record(rec)))        # its own digest right: the files' are gone
    assert bw(capsys, tmp_path, sc)[0] == 0
    assert fakes.ran() == ["modes"]


def test_unconverged_results_exit_3_and_are_listed(tmp_path, capsys, fakes, monkeypatch):
    sc = write_scene(tmp_path, ["wear", "report"])
    monkeypatch.setenv("FAKE_UNCONVERGED", "hb")
    rc, _, err = bw(capsys, tmp_path, sc)
    assert rc == 3, err
    assert "unconverged" in err and "exit status 3" in err and "Traceback" not in err
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert list(s["unconverged"]) == ["hb"] and "did not converge" in s["unconverged"]["hb"][0]
    assert "hb: not converged:" in (tmp_path / "out" / "run.log").read_text()
    assert "did not converge" in (tmp_path / "out" / "report" / "report.md").read_text()
    # Cached: the entry keeps its summary, so a rerun says the same (and exits 3 again).
    fakes.ran()
    monkeypatch.delenv("FAKE_UNCONVERGED")
    rc, _, _ = bw(capsys, tmp_path, sc)
    assert rc == 3 and fakes.ran() == []


def test_a_check_above_its_tolerance_is_printed_and_listed_exit_0(tmp_path, capsys, fakes, monkeypatch):
    """A converged result whose check exceeds its tolerance is no unconverged result (exit 0),
    but it is said: one warning line on the terminal, summary.json "warnings", the log."""
    monkeypatch.setenv("FAKE_WARNING", "hb")
    rc, _, err = bw(capsys, tmp_path, write_scene(tmp_path, ["frf"]))
    assert rc == 0 and "Traceback" not in err
    assert "warning: hb: Nh-check: the peak moves by 5.00e-03" in err
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["unconverged"] == {} and list(s["warnings"]) == ["hb"]
    assert "hb: check: Nh-check" in (tmp_path / "out" / "run.log").read_text()


def test_all_converged_exit_0_empty_unconverged(tmp_path, capsys, fakes):
    rc, _, err = bw(capsys, tmp_path, write_scene(tmp_path, ["frf"]))
    assert rc == 0, err
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["unconverged"] == {}


def test_help_documents_exit_codes(capsys):
    with pytest.raises(SystemExit):
        run(capsys, "--help")
    out = capsys.readouterr().out
    for code in ("0 ", "2 ", "3 ", "130"):
        assert f"\n  {code}" in out
    assert "unconverged" in out


def test_a_table_cell_with_a_comma_stays_one_cell(tmp_path):
    """write_rows quotes a cell that holds a comma or a quote (a march's stop reason does), so
    the file reads back as the rows written; floats keep 9 significant digits."""
    import csv

    from workflow.io import write_rows

    rows = [{"grid": "4x2", "reason": 'steady (70 steps, 4 rejected, "none" lost)', "seconds": 1.0 / 3.0},
            {"grid": "7x3", "reason": "max steps (1500)", "seconds": 2.0}]
    back = list(csv.DictReader(open(write_rows(tmp_path / "t.csv", rows))))
    assert [r["reason"] for r in back] == [r["reason"] for r in rows]
    assert [r["seconds"] for r in back] == ["0.333333333", "2"]
