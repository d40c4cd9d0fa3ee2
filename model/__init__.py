"""Contact-condition-guided diffusion model (issue 6: not yet built)."""
