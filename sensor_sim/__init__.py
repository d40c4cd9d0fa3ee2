"""The simulated tactile sensor: elastomer contact mechanics and sensor optics."""
