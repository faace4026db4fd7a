"""The learning algorithms' pure cores: PPO's update, losses, per-term GAE, the KL-adaptive
rate and running normalisation (paper Table tab:PPO), and DAgger's imitation update with the
recurrent unroll it learns through. No Zenoh, no sim: tensors in, tensors out."""
