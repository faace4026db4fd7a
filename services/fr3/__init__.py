"""The Franka Research 3 as every service sees it: limits, home pose, model file, kinematics,
and the reflexes its controller raises on bad references."""
