"""Named trajectories expanded into steps (issue 4: not yet built)."""
