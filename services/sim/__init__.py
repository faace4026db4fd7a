"""The sim service: a vectorized MuJoCo FR3 with procedural cuboid scenes and objects.

Parts: `robot` (the project's FR3 model, shared with Pinocchio), `scene` (procedural
cuboid scenes), `objects` (the object library). The vector environment and its Zenoh shell
are built on them.
"""
