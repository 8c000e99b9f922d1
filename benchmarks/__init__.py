"""claychain benchmarks."""
