"""The project's base error types.

Everything raised on purpose derives from ``ToolError``: the command line turns it into
one line naming the file, key, device or value, never a traceback.
"""

from __future__ import annotations


class ToolError(Exception):
    """Base class of everything this project raises on purpose."""


class ConfigError(ToolError):
    """A configuration, protocol, model or metadata file (or an option) is missing, malformed or
    out of range. The message names the file, the key and what was expected.
    """

    def __init__(self, path: str, key: str, message: str):
        self.path = path
        self.key = key
        super().__init__(f"{path}: [{key}] {message}")
