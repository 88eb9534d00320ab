"""Step 3 (§3.3): sections of the muscle (parallel planes, or isolines of a harmonic field after
Modenese & Kohout 2020) and the template's slices morphed onto them."""
