"""Numerics shared by the mechanisms: loop closure, roots, integrators, time base, checks, array types."""
