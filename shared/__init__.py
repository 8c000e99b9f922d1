"""claychain shared."""
