"""The engine's Archard wear against the references of :mod:`workflow.verification.wear_exact` (issue 48, 4 a, b, d).

``python -m workflow.bench.wear_references --out DIR [--quick] [--no-oscillator]``

Writes ``wear_references.csv`` and ``wear_references.json``: rows (case, quantity, value,
exact, error) — ``error`` relative, against the scale named in the quantity (the shape of
summary.json ``verification.wear_rows``).

The cases (a) ``jenkins``, (b) ``punch``, (d) ``oscillator`` (slow, ~2 min) are those of
:mod:`workflow.verification.wear_runner`.
"""
from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from workflow.verification.wear_runner import jenkins_rows, oscillator_rows, punch_layer_rows, punch_rows


def run(out: Path, quick: bool = False, oscillator_case: bool = True) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    rows = (jenkins_rows(quick) + punch_rows(quick) + punch_layer_rows(quick)
            + (oscillator_rows() if oscillator_case else []))
    with open(out / "wear_references.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["case", "quantity", "value", "exact", "error"])
        w.writeheader()
        w.writerows(rows)
    (out / "wear_references.json").write_text(json.dumps({"wear_rows": rows}, indent=1))
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("results/bench"))
    ap.add_argument("--quick", action="store_true", help="skip the slowest engine runs")
    ap.add_argument("--no-oscillator", action="store_true", help="skip case (d) (~2 min)")
    a = ap.parse_args(argv)
    for r in run(a.out, a.quick, not a.no_oscillator):
        print(f"{r['case']:10s} {r['quantity']:70s} {r['value']: .6e} {r['exact']: .6e} {r['error']:.2e}")


if __name__ == "__main__":
    main()
