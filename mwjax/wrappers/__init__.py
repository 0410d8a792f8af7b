"""Adapters over the functional core."""
