"""Contact-condition-guided diffusion model.

Built: the configuration and presets (config.py), the denoiser (network.py), the
diffusion loss and samplers (diffusion.py), the evaluation metrics (metrics.py,
markers.py), the trainer with exact resume and safetensors checkpoints (trainer.py)
and the `train` command. Not yet: validation samples, accelerate, `generate`,
`evaluate` and its report.
"""
