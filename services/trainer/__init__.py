"""The trainer, laid out by role as rsl_rl lays out its own: `algorithms` (PPO and DAgger
behind one `Algorithm` interface, and their pure cores), `storage` (decoding the rollout chunks workers stream), `collection` (rollout
workers and the sources a run collects through), `runners` (the training loop, its config,
snapshots and ranks) and `results` (evaluation, summary, curves); the command lines
(`cli`, `rollout_cli`) and what the trainer publishes (`publisher`) at the
top. The whole in-process loop, top to bottom in one file: `examples/train_loop.py`."""
