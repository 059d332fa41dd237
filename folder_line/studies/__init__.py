"""Design studies: sweeps, boundary solves, optimisation and Monte Carlo over scene keys, on Dask."""
