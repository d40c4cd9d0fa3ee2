"""LeRobotDataset v3.0 folders, both ways: runs (or a split) exported for the robot-learning ecosystem, and
such a folder imported back into run files (docs/dataset.md, "LeRobot")."""
