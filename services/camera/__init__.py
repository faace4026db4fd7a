"""The camera service: depth frames of the robot's cameras on `camera/<w>/frames`."""
