"""Training: the configs settled, the trainer and its callbacks built and run (the ``train`` command's job)."""
