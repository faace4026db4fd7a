"""The safety service: every command to a robot, simulated or real, passes here.

Batched pipeline from a raw policy action to a safe command: non-finite guard, action
scaling and magnitude bound, Cartesian clipping, EMA smoothing, joint limits, jerk-limited
references (Ruckig) and torque pre-clipping, with a watchdog.
"""
