"""Shapes as data, their gmsh models and tagged meshes, and the rigid indenters."""
