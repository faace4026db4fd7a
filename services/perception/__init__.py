"""The perception service: point clouds of the scene and object, and UniCORN tokens.

Environment clouds sampled from the visible faces of the scene's cuboids, object clouds
posed every step, the local (focal) cloud around the object, the UniCORN patch encoder, and
the depth-camera path (open3d) that a real robot uses instead of the analytic clouds.
"""
