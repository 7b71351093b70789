"""Global numbering, Dirichlet conditions, and assembly of local AD forces and tangents."""
