"""Supervision of the benchmark turbine: the UIO bank of seed 000, speed-sensor FDI, fault-tolerant estimates."""
