"""claychain micro."""
