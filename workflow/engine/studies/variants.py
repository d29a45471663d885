"""HB variants: formulation × Nh × nit, and how a set of them is shared over MPI ranks."""
from __future__ import annotations

from dataclasses import dataclass

from workflow.engine.errors import SceneError
from workflow.engine.fourier import default_nit


@dataclass(frozen=True)
class Variant:
    """One HB formulation to sweep: method, Nh, nit (already resolved, ≥ 2Nh+1)."""

    method: str
    nh: int
    nit: int

    @property
    def collocated(self) -> bool:
        """nit = 2Nh+1 (the HDHB grid)."""
        return self.nit == 2 * self.nh + 1

    @property
    def nit_label(self) -> str:
        return "2Nh+1" if self.collocated else str(self.nit)

    @property
    def label(self) -> str:
        return f"{self.method.upper()}-{self.nh} nit={self.nit}"


def resolved_nit(method: str, nh: int, nit: int) -> int:
    """A scene's nit for ``method`` at ``nh``: ``nit`` itself, or for 0 the default
    (:func:`workflow.engine.fourier.default_nit`; HDHB, whose unknowns are the samples, 2Nh+1)."""
    return int(nit) or (2 * int(nh) + 1 if method == "hdhb" else default_nit(int(nh)))


def variants(hb) -> list[Variant]:
    """method ∈ hb.methods × Nh ∈ hb.harmonics × nit ∈ hb.time_samples (0 →
    :func:`workflow.engine.fourier.default_nit`; HDHB: 2Nh+1).

    HDHB runs only with nit = 2Nh+1 (other nit values are skipped for it, 0 gives it 2Nh+1);
    duplicates (e.g. nit = 0 and nit = 2Nh+1 both listed) are dropped. Order:
    as listed in the scene (method-major).
    """
    out: list[Variant] = []
    for method in hb.methods:
        for nh in hb.harmonics:
            for nit in hb.time_samples:
                n = resolved_nit(method, int(nh), int(nit))
                if n < 2 * int(nh) + 1:
                    raise SceneError(f"hb.time_samples = {nit} < 2·Nh+1 = {2 * int(nh) + 1} for hb.harmonics = {nh}")
                if method == "hdhb" and n != 2 * int(nh) + 1:
                    continue
                v = Variant(method, int(nh), n)
                if v not in out:
                    out.append(v)
    return out


# ---------------------------------------------------------- linear helpers


def cost(v: Variant) -> float:
    """Relative cost of sweeping ``v``: ~ (2Nh+1)² (measured 0.24 / 0.55 / 2.2 / 9.5 s
    for HBM nit=105 at Nh = 1/3/7/17), a little more with nit."""
    return (2 * v.nh + 1) ** 2 * (1.0 + v.nit / 400.0)


def share(todo: list, size: int) -> list[list[int]]:
    """Indices of ``todo`` per rank: the most expensive variant first, each onto
    the rank with the least work so far (cost ~ (2Nh+1)², measured 0.24 / 0.55 /
    2.2 / 9.5 s for HBM nit=105 at Nh = 1/3/7/17). Deterministic: every rank
    computes the same split."""
    cost_ = [cost(v) for v in todo]
    load = [0.0] * size
    out: list[list[int]] = [[] for _ in range(size)]
    for i in sorted(range(len(todo)), key=lambda k: (-cost_[k], k)):
        r = min(range(size), key=lambda k: (load[k], k))
        out[r].append(i)
        load[r] += cost_[i]
    return [sorted(o) for o in out]
