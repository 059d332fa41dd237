"""The mechanisms of the papers: the L six-bar, the F knife and cyclogram, the D delivery, drives."""
