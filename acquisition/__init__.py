"""Synchronised capture of tactile frame + wrench + pose into HDF5 (issue 4: not yet built)."""
