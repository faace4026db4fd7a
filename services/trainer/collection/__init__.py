"""Collecting experience: the rollout workers' cores (sim, perception, policy and the safety
filter's training profile in one loop; DAgger's with a teacher labelling), the sources a
runner collects through (in process, or streamed from `hamnet rollout` workers over Zenoh)
and the worker service itself."""
