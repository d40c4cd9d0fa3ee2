"""Contact-condition-guided diffusion model: object image at the contact pose + wrench → tactile image.

config.py (ModelConfig, presets) · registry.py (which network) → network.py (the U-Net) ·
diffusion.py (schedule, loss, guided denoiser) → samplers.py (DDIM, DDPM, DPM-Solver++) ·
trainer.py (the loop) + callbacks.py (progress, validation images, checkpoints), joined by
build.py · checkpoint.py (safetensors + JSON) · inference.py (``generate``) · evaluate.py,
metrics.py, markers.py, baseline.py, figures.py (``evaluate`` and its report). The commands: ``train`` in
cli/model_app.py, ``generate``, ``evaluate`` and ``compare`` in cli/*_cmd.py; each parses its options and calls
its job here (train_job.py, generate_job.py, evaluate_job.py, compare_job.py).
"""
