"""What the trainer stores and reads of collected experience: the rollout chunks streamed by
workers decoded into PPO's `Rollout` or DAgger's `Demonstrations` (the rollout record itself
and its wire format live below the trainer, in `hamnet.policy.rollout_record` and
`hamnet.policy.chunk_codec`, since the policy service writes them too)."""
