"""Benchmarks and convergence studies (scripts: python -m workflow.bench.<name>)."""
