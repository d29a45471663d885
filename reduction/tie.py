"""Tied midside nodes of a linear contact surface: they follow their edges in the reduction.

The bundle's ``contact.tie`` rows ``(dep, a, b)`` ask ``u_dep = (u_a + u_b)/2``
(``geometry.contact_nodes = "linear"``: every midside node of a flank facet
follows its edge, :func:`reduction.pairs.tie_midsides`). The reductions
(:func:`reduction.reduce.reduce_with_basis`, :mod:`reduction.parallel`) hold the
dependent DOFs with the boundary in their fixed-interface modes, and solve the constraint modes of the
kept DOFs alone with the dependent ones following, ``q_b = T q_b'``
(:func:`tie_map`): the constraint mode of a master DOF is the static response
to it with the other kept DOFs held, ``Ψ_a + ½ Σ Ψ_dep``, one solve with the
right-hand side ``K_ib T``.

This *is* the Craig–Bampton reduction of the constrained structure, not an
approximation of it (test: ``tests/reduction/test_tie.py`` against the
reduction of the explicitly constrained full model). Solving for the kept DOFs
alone, rather than for every boundary DOF and eliminating the dependent ones
after the projection, makes V a quarter as wide on a linear contact surface
(three midside DOFs tied to every vertex DOF).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from workflow.errors import BundleError


def tie_matrix(m: int, tie_pos: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(T, keep)`` for ``m`` unknowns and tie rows given as positions among
    them, ``(dep, a, b)``: ``T`` (m, m − k) keeps every other unknown and
    writes ``x_dep = (x_a + x_b)/2``; ``keep`` lists the kept unknowns."""
    tie_pos = np.asarray(tie_pos, dtype=np.int64).reshape(-1, 3)
    dep = tie_pos[:, 0]
    keep = np.setdiff1d(np.arange(m), dep)
    col = -np.ones(m, dtype=np.int64)
    col[keep] = np.arange(keep.size)
    rows = np.concatenate([keep, dep, dep])
    cols = np.concatenate([col[keep], col[tie_pos[:, 1]], col[tie_pos[:, 2]]])
    vals = np.concatenate([np.ones(keep.size), np.full(2 * dep.size, 0.5)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(m, keep.size)), keep


def tie_map(boundary: np.ndarray, tie: np.ndarray, m: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(T, keep)``: the (m, m − k) map ``q = T q'`` and the kept coordinates of q.

    ``boundary``: the sorted full DOF indices of the first coordinates of q
    (:func:`reduction.reduce.boundary_dofs`); ``tie``: (k, 3) DOF rows.
    """
    tie = np.asarray(tie, dtype=np.int64).reshape(-1, 3)
    pos = np.searchsorted(boundary, tie)
    if np.any(pos >= len(boundary)) or np.any(boundary[np.minimum(pos, len(boundary) - 1)] != tie):
        raise BundleError("contact.tie: a tied or master DOF is not a boundary DOF of the reduction")
    return tie_matrix(m, pos)


def boundary_map(boundary: np.ndarray, tie) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(T_b, kept)``: the boundary DOFs ``boundary`` (sorted full indices) as a map of the kept
    ones, ``q_b = T_b q_b'`` (:func:`tie_map`), or the identity without ``tie``; ``kept`` their
    positions in ``boundary``. The reductions solve the constraint modes of ``K_ib T_b``."""
    if tie is None:
        return sp.identity(len(boundary), format="csr"), np.arange(len(boundary))
    return tie_map(boundary, tie, len(boundary))


def tie_pairs(contact) -> np.ndarray:
    """(k_m, 2) pair indices of the edge ends of each tied blade midside node
    (the x-component rows of the blade side), for checks and reports."""
    t = np.asarray(contact.tie, dtype=np.int64)
    of = {int(d): i for i, d in enumerate(np.asarray(contact.blade_dofs)[:, 0])}
    rows = [r for r in t if int(r[1]) in of and int(r[2]) in of]
    return np.array([(of[int(r[1])], of[int(r[2])]) for r in rows], dtype=np.int64).reshape(-1, 2)
