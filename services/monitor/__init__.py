"""The monitor: a live Rerun view of the whole stack, in its own process.

Robot, scene, clouds, module activations, rewards, safety events and trainer metrics of
one environment in focus; frames are dropped rather than queued so that watching never
slows the control loop.
"""
