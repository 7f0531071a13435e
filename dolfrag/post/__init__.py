"""Post-processing: reads the state, never changes it."""
