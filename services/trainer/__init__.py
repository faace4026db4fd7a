"""The trainer: PPO (and later DAgger) on rollouts, with pure batched cores for advantages,
losses, learning-rate adaptation and normalization (paper Table tab:PPO; the authors'
`rss_train.yaml` where they differ)."""
