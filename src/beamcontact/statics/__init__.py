"""Static equilibrium by load stepping."""
