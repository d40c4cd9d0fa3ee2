"""The objects pressed on the sensor: indenter geometry (height maps), object images, the pose."""
