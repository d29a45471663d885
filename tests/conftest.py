"""Imported before any test module: ``import workflow`` chooses OpenBLAS's kernels from the CPU
before NumPy loads it (:mod:`workflow.blas_kernels`), in this process and in the workers and
subprocesses it starts."""
import workflow  # noqa: F401
