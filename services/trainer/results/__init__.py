"""What a finished run reports: held-out evaluation of its policy, its summary file and its
learning curves as PNG."""
