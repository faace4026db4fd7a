"""The real-robot bridge: the FR3 behind the same contract as the sim (`hamnet bridge`)."""
