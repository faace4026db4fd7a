"""The task every service agrees on: the slots of a scene's cuboids, the reward terms and
the physics parameters an episode draws. Names only, no behaviour: the sim produces them,
perception, the policy, the trainer and the monitor read them.
"""
