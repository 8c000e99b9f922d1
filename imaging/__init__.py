"""claychain imaging."""
