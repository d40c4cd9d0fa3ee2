"""HDF5 runs to validated, merged and split training data (issue 5: not yet built)."""
