"""Protocols: TOML files (library/) checked and expanded into a list of steps; imports no rig (docs/protocols.md)."""
