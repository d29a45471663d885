"""The engine's Archard wear against the references of :mod:`workflow.verification.wear_exact` (issue 48, 4 a, b, d).

``python -m workflow.bench.wear_references --out DIR [--quick] [--no-oscillator]``

Writes ``wear_references.csv`` and ``wear_references.json``: rows (case, quantity, value,
exact, error) — ``error`` relative, against the scale named in the quantity (the shape of
summary.json ``verification.wear_rows``).

* (a) ``jenkins``: :class:`~workflow.verification.wear_exact.JenkinsWear` (k_t = 1e5 N/m,
  k_n = 1e7 N/m, μ = 0.5, X = 0.1 mm, N₀ = 15 N, A = 1 mm², k_w = 2.5e-16 m²/N: r = 1e-6 /cycle,
  N_c = 20 N, δ₀ = 1.5 µm), lumped model ``JenkinsWear.model()``, ε = (k_n, k_t) (the
  automatic penalty picks exactly these: massless node), HBM Nh = 3, nit = 64, at
  100/π Hz; through :func:`workflow.engine.worn_steady_state`. Also ε = 10 k_t (the
  ε-check's penalty), where the DLFT predictor is no longer the exact drive.
* (b) ``punch``: :class:`~workflow.verification.wear_exact.PunchWear`, three contacts
  (edges A = 1.5 mm², gap 2 µm; centre 1 mm², no gap), N₀ = 12 N, k_w = 1e-15: persistent
  slip (no worn steady state); the march's W(n), its final rates against the sinking speed V
  and the worn profile's offset against the closed forms.
* (d) ``oscillator`` (slow, ~2 min): :class:`~workflow.verification.wear_exact.OscillatorWear`
  at the tied resonance, reference by event-driven steady states and cycle jumps.
"""
from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from workflow.verification.wear_runner import jenkins_rows, oscillator_rows, punch_rows


def run(out: Path, quick: bool = False, oscillator_case: bool = True) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    rows = jenkins_rows(quick) + punch_rows(quick) + (oscillator_rows() if oscillator_case else [])
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
