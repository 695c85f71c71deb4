"""Farm supervision of seed 001: fault detection (the paper's and ours), dispatch and the PI reference controller."""
