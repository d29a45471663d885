"""bladewear's workflow: scenes, stages, the numerical engine (:mod:`workflow.engine`) and reports.

Importing it first chooses OpenBLAS's kernels from the CPU where OpenBLAS would not know it
(:mod:`workflow.blas_kernels`), before NumPy loads OpenBLAS.
"""
from workflow import blas_kernels as _blas_kernels

_blas_kernels.choose()
