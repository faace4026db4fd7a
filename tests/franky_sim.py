"""franky-sim for tests: the product's (`hamnet.bridge.franky_sim`)."""

from hamnet.bridge.franky_sim import franky_sim

__all__ = ["franky_sim"]
