"""Numerical studies: each runs a method where it is known to fail beside one that works and
measures the failure (`stability`: `fingertip study stability --out DIR`)."""
