"""Matplotlib curves and pyvista pictures of a run."""
