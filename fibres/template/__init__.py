"""Step 1 of Kohout et al. (GRAPP 2012, §3.1): fibre templates in the unit cube, Sobol samples."""
