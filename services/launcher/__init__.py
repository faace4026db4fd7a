"""`hamnet up`: run a stack file (compose/*.yaml) as supervised processes linked by Zenoh."""
