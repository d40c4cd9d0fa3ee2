"""Contact-condition-guided diffusion model: object image at the contact pose + wrench → tactile image.

Seven sub-packages, each importing only those listed before it (``MODEL_ROOMS`` in tests/test_layers.py):
denoiser/ (config, network, diffusion, samplers, checkpoints) · conditioning/ (the physics channels and
their caches beside the split, whose places cache.py alone knows) · generation/ (``TrainedModel``, ``generate``) ·
sweeps/ (the force sweep) · evaluation/ (``evaluate``: metrics, baselines, report, figures) · training/
(trainer, callbacks, ``train``) · compare/ (``compare``). The commands: ``train`` in cli/model_app.py,
``generate``, ``evaluate`` and ``compare`` in cli/*_cmd.py; each parses its options and calls its job
here (training/train_job.py, generation/generate_job.py, evaluation/evaluate_job.py, compare/compare_job.py).
"""
