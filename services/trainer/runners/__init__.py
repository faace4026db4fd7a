"""Runs: what a run is (`RunConfig`), the loop that collects, learns, logs and checkpoints
(`Runner`, the same for every algorithm), its resumable snapshots, ranks of learner
processes and how a run is stopped between two steps."""
