"""The reduced model: what the dynamics needs of the structure, and nothing more.

Craig–Bampton (or any other) coordinates ``q`` with small dense matrices,
the map ``B`` from ``q`` to relative contact displacements in each pair's
(n, t1, t2) frame, and the reduced loads. See ``docs/contracts.md`` §4.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import zipfile

from workflow.engine.errors import BundleError
from workflow.engine.files import write_npz

_ARRAYS = ("M", "K", "C", "B", "f_static", "f_harmonic", "O", "area", "gap", "flank", "position")


@dataclass
class ReducedModel:
    """Reduced matrices and contact data (SI units).

    ``M``, ``K``, ``C``: (m, m) reduced mass [kg], stiffness [N/m], damping
    [N s/m]. ``B``: (3p, m), q → u_r pair-major ``[n, t1, t2]`` [m/m].
    ``f_static``, ``f_harmonic``: (m,) reduced static load and amplitude of the
    cos(ωt) excitation [N]. ``O``: (n_obs, m), q → observed DOFs. ``area``
    [m²], ``gap`` [m], ``flank`` (0 intrados, 1 extrados): (p,).
    ``position``: (p, 3) [m]. ``info``: provenance (modes kept, boundary DOFs,
    timings) — JSON-serialisable. ``mu``: optional (p,) friction coefficient
    of each pair from the bundle's ``contact.npz`` (None: the scene's
    ``contact.mu``); use :meth:`friction`, never ``mu`` directly.
    """

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    B: np.ndarray
    f_static: np.ndarray
    f_harmonic: np.ndarray
    O: np.ndarray
    area: np.ndarray
    gap: np.ndarray
    flank: np.ndarray
    position: np.ndarray
    info: dict = field(default_factory=dict)
    mu: np.ndarray | None = None

    @property
    def n_pairs(self) -> int:
        return self.B.shape[0] // 3

    @property
    def size(self) -> int:
        return self.M.shape[0]

    def save(self, path: str | Path) -> Path:
        """Write one ``.npz`` atomically."""
        import json

        extra = {} if self.mu is None else {"mu": np.asarray(self.mu, float)}
        return write_npz(path, info=np.array(json.dumps(self.info, default=str)),
                         **{k: getattr(self, k) for k in _ARRAYS}, **extra)

    @classmethod
    def load(cls, path: str | Path) -> "ReducedModel":
        import json

        path = Path(path)
        try:
            with np.load(path) as z:
                arrays = {k: z[k] for k in _ARRAYS}
                info = json.loads(str(z["info"])) if "info" in z else {}
                mu = z["mu"] if "mu" in z else None  # files written before per-pair μ have none
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise BundleError(f"reduced model {path} cannot be read: {exc}") from exc
        model = cls(**arrays, info=info, mu=mu)
        model.validate()
        return model

    def validate(self) -> None:
        """Raise :class:`BundleError` naming the first inconsistent field."""
        m = self.M.shape[0]
        for k in ("M", "K", "C"):
            if getattr(self, k).shape != (m, m):
                raise BundleError(f"reduced model {k} is {getattr(self, k).shape}, expected ({m}, {m})")
        if self.B.ndim != 2 or self.B.shape[1] != m or self.B.shape[0] % 3:
            raise BundleError(f"reduced model B is {self.B.shape}, expected (3p, {m})")
        p = self.n_pairs
        for k in ("f_static", "f_harmonic"):
            if getattr(self, k).shape != (m,):
                raise BundleError(f"reduced model {k} is {getattr(self, k).shape}, expected ({m},)")
        for k in ("area", "gap", "flank"):
            if getattr(self, k).shape != (p,):
                raise BundleError(f"reduced model {k} is {getattr(self, k).shape}, expected ({p},)")
        if self.mu is not None:
            mu = np.asarray(self.mu)
            if mu.shape != (p,) or not np.all(np.isfinite(mu)) or np.any(mu < 0):
                raise BundleError(f"reduced model mu must be ({p},) finite values ≥ 0, got shape {mu.shape}")
        if self.O.ndim != 2 or self.O.shape[1] != m:
            raise BundleError(f"reduced model O is {self.O.shape}, expected (n_obs, {m})")
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray) and v.dtype.kind == "f" and not np.all(np.isfinite(v)):
                raise BundleError(f"reduced model {f.name} has non-finite entries")

    def friction(self, mu_scene: float) -> tuple[np.ndarray, str]:
        """Friction coefficient of each pair, ``(mu (p,), source)``.

        The bundle's per-pair ``mu`` when it has one (``source`` =
        ``"bundle contact.npz"``), else ``mu_scene`` (the scene's
        ``contact.mu``) on every pair (``source`` = ``"scene contact.mu"``).
        The harmonic-balance and wear stages take μ from here and report the
        source in their summaries.
        """
        if self.mu is not None:
            return np.asarray(self.mu, dtype=float).copy(), "bundle contact.npz"
        return np.full(self.n_pairs, float(mu_scene)), "scene contact.mu"
