"""Beam-to-beam contact (paper Sec. 2): integration points, broad phase, pair laws, and
rigid obstacles."""
