"""Step 4 (§3.4): attachment areas and patches, fibre ends spread over them, trimming and reconstruction."""
