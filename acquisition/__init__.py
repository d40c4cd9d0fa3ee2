"""Synchronised capture of tactile frame + wrench + pose into HDF5 run files (docs/run-file.md)."""
