"""The policy service: HAMnet, its baselines, and batched inference with hot-reloaded weights.

Modulation network, module banks and gates, actor and critic base networks, the baselines
of the paper's ablations, and the student network that runs on the real robot.
"""
