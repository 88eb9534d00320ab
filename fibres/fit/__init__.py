"""Step 2 (§3.2): the template cube fitted to the muscle (principal axis, oriented box)."""
