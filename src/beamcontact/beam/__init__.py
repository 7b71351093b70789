"""Planar rotation-free Bernoulli-Euler beam (paper Sec. 3): sections, meshes, local energies."""
