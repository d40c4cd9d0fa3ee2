"""Contact-condition-guided diffusion model.

Built: the configuration and presets (config.py), the denoiser (network.py), the
diffusion loss and samplers (diffusion.py), the evaluation metrics (metrics.py,
markers.py). Not yet: the `train`, `generate` and `evaluate` commands (trainer,
checkpoints, reports).
"""
