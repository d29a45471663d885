"""A lumped tuned bladed disk: N identical sectors of 3D point masses on a circle.

Sector 0 (positions in x axial, y circumferential, z radial at its centre line):

====  =====================  ==========================================
node  name                   role
====  =====================  ==========================================
0     c   disk rim, angle −α/2   low cyclic face (half its mass, half its ground spring)
1     w   disk web, angle 0      interior
2,3   d1, d2  disk lugs          contact (disk side)
4,5   b1, b2  blade root         contact (blade side, same places as d1, d2)
6     t   blade tip              excited and observed
7     c'  disk rim, angle +α/2   high cyclic face = sector 1's c (the other halves)
====  =====================  ==========================================

Springs are random 3×3 symmetric positive-definite tensors (the same in
every sector, rotated with it), so the rotation R of the cyclic map
matters. The full disk is the sum of sector 0's matrices rotated by R^s and
scattered onto sector s's nodes (c' of sector s = c of sector s+1): the
independent reference of the cyclic reduction. Pairs: (b1, d1), (b2, d2)
with dovetail-like normals (from disk into blade, radially inwards); the
centrifugal-like static load pulls the blade out, so both flanks carry a
normal load. Tip load: sector s gets ``R^s F e^{i s 2π EO/N}`` (the EO wave).
Units: SI-like (m, kg, N), values of order 1.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from reduction.bundle import Bundle, Contact, Cyclic, Loads
from reduction.cyclic import rotation_x
from workflow.engine.model import ReducedModel

NODES = 8
#: (node a, node b or −1 for ground, stiffness scale)
SPRINGS = [(0, 1, 40.0), (1, 7, 40.0), (1, 2, 30.0), (1, 3, 30.0), (0, 2, 20.0), (3, 7, 20.0), (2, 3, 10.0),
           (4, 5, 15.0), (4, 6, 3.0), (5, 6, 3.0), (0, -1, 50.0), (7, -1, 50.0)]
MASS = [0.5, 1.0, 0.3, 0.3, 0.3, 0.3, 0.4, 0.5]
#: radius [m], angle as a fraction of α, axial x [m]
PLACES = [(1.0, -0.5, 0.0), (0.9, 0.0, 0.05), (1.2, -0.2, 0.1), (1.2, 0.2, -0.1), (1.2, -0.2, 0.1),
          (1.2, 0.2, -0.1), (1.8, 0.0, 0.0), (1.0, 0.5, 0.0)]
PAIRS = [(4, 2, +1.0), (5, 3, -1.0)]  # (blade node, disk node, side of the flank)
TIP, LOW, HIGH = 6, 0, 7


def _spd(rng, scale):
    A = rng.standard_normal((3, 3))
    return scale * (A @ A.T / 3.0 + 0.5 * np.eye(3))


def _dofs(node):
    return 3 * node + np.arange(3)


def sector_matrices(n_sectors: int, seed: int = 0, damping=(0.02, 2e-4), preload: float = 4.0):
    """Sector 0: ``(M, K, C, frames (p,3,3), f_static, positions)`` on NODES nodes.

    The ground springs of c and c' are each half of one tensor (c' rotated),
    and so are their masses: folded by the cyclic map they make one rim node.
    ``damping`` = (a, b): C = a M + b K. ``preload`` [N]: radial pull on the blade nodes.
    """
    rng = np.random.default_rng(seed)
    R = rotation_x(2 * np.pi / n_sectors)
    n = 3 * NODES
    K, M = np.zeros((n, n)), np.zeros((n, n))
    ground = _spd(rng, SPRINGS[-1][2])
    for a, b, k in SPRINGS:
        S = 0.5 * ground if a == 0 and b < 0 else (0.5 * R @ ground @ R.T if b < 0 else _spd(rng, k))
        K[np.ix_(_dofs(a), _dofs(a))] += S
        if b >= 0:
            K[np.ix_(_dofs(b), _dofs(b))] += S
            K[np.ix_(_dofs(a), _dofs(b))] -= S
            K[np.ix_(_dofs(b), _dofs(a))] -= S
    for i, m in enumerate(MASS):
        M[_dofs(i), _dofs(i)] = m
    alpha = 2 * np.pi / n_sectors
    pos = np.array([rotation_x(f * alpha) @ [x, 0.0, r] for r, f, x in PLACES])
    frames, f_static = [], np.zeros(n)
    for b, _, side in PAIRS:
        er = pos[b] / np.linalg.norm(pos[b])
        et = np.cross([1.0, 0.0, 0.0], er)
        nrm = -er + 0.2 * side * et
        nrm /= np.linalg.norm(nrm)
        t1 = np.array([1.0, 0.0, 0.0])
        frames.append(np.stack([nrm, t1, np.cross(nrm, t1)]))
    for node in (4, 5, 6):
        f_static[_dofs(node)] = preload * pos[node] / np.linalg.norm(pos[node]) * (1.5 if node == 6 else 1.0)
    C = damping[0] * M + damping[1] * K
    return M, K, C, np.array(frames), f_static, pos


def tip_force(amplitude: float = 1.0) -> np.ndarray:
    """Sector 0's complex tip-force amplitude (3,) [N]: axial and circumferential."""
    return amplitude * np.array([0.6, 1.0, 0.1])


def sector_bundle(n_sectors: int, seed: int = 0, amplitude: float = 1.0, **kw) -> Bundle:
    """Sector 0 as a cyclic model bundle (cyclic faces: c and c')."""
    M, K, C, frames, fs, pos = sector_matrices(n_sectors, seed, **kw)
    n = 3 * NODES
    fh = np.zeros(n)
    fh[_dofs(TIP)] = tip_force(amplitude)
    p = len(PAIRS)
    contact = Contact(blade_dofs=np.array([_dofs(b) for b, _, _ in PAIRS]),
                      disk_dofs=np.array([_dofs(d) for _, d, _ in PAIRS]), normal=frames[:, 0], t1=frames[:, 1],
                      t2=frames[:, 2], area=np.full(p, 1e-4), gap=np.zeros(p), flank=np.arange(p),
                      position=pos[[b for b, _, _ in PAIRS]])
    loads = Loads(fixed=np.zeros(0, np.int64), static=fs, harmonic=fh, observe=_dofs(TIP))
    return Bundle(M=sp.csr_matrix(M), K=sp.csr_matrix(K), C=sp.csr_matrix(C), contact=contact, loads=loads,
                  coords=pos, cyclic=Cyclic(low_dofs=_dofs(LOW)[None], high_dofs=_dofs(HIGH)[None],
                                            n_sectors=n_sectors))


def full_disk(n_sectors: int, engine_order: int, seed: int = 0, amplitude: float = 1.0, blade_stiffness=None,
              **kw) -> ReducedModel:
    """The whole disk as an ordinary (physical-coordinate) ReducedModel.

    Sector s owns nodes 7s … 7s+6 (c, w, d1, d2, b1, b2, t); its c' is node
    7(s+1 mod N). Pairs sector-major (sector 0's first, as in the sector
    model); observed: every tip, sector-major; ``f_harmonic`` complex, the
    EO wave. ``blade_stiffness``: (N,) deviations δ_s — sector s's blade springs (nodes b1, b2,
    t) × (1 + δ_s), its damping the same Rayleigh law on them (a mistuned disk).
    """
    M0, K0, C0, frames, fs0, pos = sector_matrices(n_sectors, seed, **kw)
    ra, rb = kw.get("damping", (0.02, 2e-4))
    blade = np.concatenate([_dofs(i) for i in (4, 5, 6)])
    dev = np.zeros(n_sectors) if blade_stiffness is None else np.asarray(blade_stiffness, float)
    N, own = n_sectors, NODES - 1
    n = 3 * own * N
    M, K, C = (np.zeros((n, n)) for _ in range(3))
    fs, fh = np.zeros(n), np.zeros(n, complex)
    B = np.zeros((3 * len(PAIRS) * N, n))
    O = np.zeros((3 * N, n))
    for s in range(N):
        Rs = rotation_x(2 * np.pi * s / N)
        Rb = np.kron(np.eye(NODES), Rs)
        nodes = [own * s + i for i in range(own)] + [own * ((s + 1) % N)]
        d = np.concatenate([_dofs(i) for i in nodes])
        Ks = K0.copy()
        Ks[np.ix_(blade, blade)] *= 1 + dev[s]   # the blade's springs touch its own nodes only
        for A, A0 in ((M, M0), (K, Ks), (C, ra * M0 + rb * Ks)):
            A[np.ix_(d, d)] += Rb @ A0 @ Rb.T
        fs[d] += Rb @ fs0
        fh[_dofs(nodes[TIP])] += Rs @ tip_force(amplitude) * np.exp(2j * np.pi * s * engine_order / N)
        for i, (b, dn, _) in enumerate(PAIRS):
            fr = frames[i] @ Rs.T  # rows n, t1, t2 rotated with the sector
            row = 3 * (len(PAIRS) * s + i) + np.arange(3)
            B[np.ix_(row, _dofs(nodes[b]))] += fr
            B[np.ix_(row, _dofs(nodes[dn]))] -= fr
        O[3 * s + np.arange(3), _dofs(nodes[TIP])] = 1.0
    p = len(PAIRS) * N
    return ReducedModel(M=M, K=K, C=C, B=B, f_static=fs, f_harmonic=fh, O=O, area=np.full(p, 1e-4),
                        gap=np.zeros(p), flank=np.tile(np.arange(len(PAIRS)), N), position=np.zeros((p, 3)))
