"""Placeholder: being written (must be replaced or deleted before commit)."""
