"""Rig control: drivers for stages, force gauges, tactile camera and HID pendant, and the simulated rig."""

__version__ = "0.1.0"
