"""Image helpers shared by the stages: gray levels and their percentiles, the camera's tone
curve undone, stripe periods of a region, ragged arrays and thread limits."""
