"""claychain macro."""
