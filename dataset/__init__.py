"""HDF5 runs to validated, merged and split training data, and the PyTorch Dataset (docs/dataset.md)."""
