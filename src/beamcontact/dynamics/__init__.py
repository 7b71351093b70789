"""Implicit dynamics: HHT-alpha (paper Sec. 3.6) with Newton-Raphson and step control."""
