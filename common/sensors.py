"""The sensor kinds of the paper, named once for protocols, the simulator and the model.

- ``rgb``: coloured lights from the sides, no markers;
- ``rgb_markers``: the same with a printed marker grid;
- ``white_markers``: white light with markers.
"""

SENSOR_KINDS = ("rgb", "rgb_markers", "white_markers")


def has_markers(kind: str) -> bool:
    return kind.endswith("_markers")
