"""The engine from Python, on your own matrices: friction-damped FRF and worn steady state.

A lumped "blade" (a root block on three friction pads, a tip mass on a
bending spring) written directly as a reduced model — any structure whose
M, K, C and contact map you have works the same way (or read a bundle with
``reduction.bundle.read_bundle`` and reduce it). Run: ``python examples/engine_on_your_matrices.py``.
"""
import numpy as np

from workflow import engine
from workflow.engine.lumped import pairs_on_block

p = 3    # pads of 1 g on 3e4 N/m: their own resonance (~870 Hz) lies well above the harmonics that matter
M, K, block, tip = pairs_on_block(p, k_n=2e6, k_t=3e4, scatter=(0.7, 0.6), m_node=1e-3, m_block=0.02, ground=5e3,
                                  m_tip=0.1, k_tip=0.2 * (2 * np.pi * 100.0) ** 2, rng=np.random.default_rng(1))
n = M.shape[0]
B = np.eye(3 * p, n)                                    # u_r = [n, t1, t2] of each pad (the ground is rigid)
f_static, f_tip, O = np.zeros(n), np.zeros(n), np.zeros((1, n))
f_static[0:3 * p:3] = -10.0                             # 10 N pressing each pad (λ_N < 0 in contact)
f_tip[tip], O[0, tip] = 0.2, 1.0                        # 0.2 N at the tip, observed there
model = engine.ReducedModel(M=M, K=K, C=1e-5 * K, B=B, f_static=f_static, f_harmonic=f_tip, O=O, area=np.full(p, 1e-6),
                            gap=np.zeros(p), flank=np.zeros(p, int), position=np.zeros((p, 3)))

law = engine.contact_law(model, mu=0.3)                 # penalties: each pad's stiffness at the unresolved harmonics
study = engine.frf(model, law, [engine.Variant("hbm", 3, 32)], band_hz=(94.0, 104.0), points=21)
run = study.runs[0]
print(f"peak {run.peak_hz():.2f} Hz, {np.nanmax(run.amplitude):.3e} m (tied {study.tied.max():.3e} m); "
      f"{run.converged_points}/{len(run.freqs_hz)} converged; change at 1.5×Nh {study.nh_check['max_rel_change']:.1e}")
# Every study judges its own convergence: here Nh = 3 is not enough (the peak moves by 4.5 % at
# Nh = 5), and the study says so. At Nh = 7, nit = 64 the change is 2.5e-5 and the peak 1.797e-4 m.
for line in study.unconverged() + study.warnings():
    print("check:", line)

worn = engine.worn_steady_state(model, law, engine.WearOptions(methods=("pseudo-time",), nh=3, nit=32,
                                                              frequency_hz=run.peak_hz()))
print(f"worn steady state: max W = {worn.histories['pseudo-time'].W.max():.3e} m, "
      f"steady = {worn.histories['pseudo-time'].steady}")
