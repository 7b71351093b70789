"""Nonlinear and linear solvers; they return status flags and never raise inside jit."""
