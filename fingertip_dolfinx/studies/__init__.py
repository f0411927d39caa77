"""Numerical studies run by `fingertip study KIND --out DIR` (e.g. `stability`: known failure
modes measured beside the methods that work; `fidelity`: model fidelity per scene)."""
