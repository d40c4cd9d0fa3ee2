"""A trained model loaded from its checkpoint and sampled: ``TrainedModel`` and the ``generate`` command's job."""
