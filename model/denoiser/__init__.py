"""The denoiser: its config and presets, the network and its registry, diffusion, samplers, checkpoints, threads."""
