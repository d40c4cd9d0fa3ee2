"""Foundation: base errors and the TOML/number checker. Imports nothing else of the project."""
