"""HAMnet stack: non-prehensile manipulation services (sim, perception, policy, safety,
trainer, monitor, recorder, bridge) linked by Eclipse Zenoh.

The folders under `services/` are the subpackages of `hamnet`; `proto/` is `hamnet.proto`.
"""

__version__ = "0.1.0"
