"""The physics channels: each frame's render (at its pose or at its Fz's depth), force augmentation, their caches."""
