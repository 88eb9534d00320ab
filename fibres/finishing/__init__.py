"""Step 5: smoothing, keeping fibres inside the surface, and the fibres' quality."""
