"""Solver plugins shipped with handeye; each module registers itself through an entry point
of the group ``handeye`` in pyproject.toml, exactly as a third-party package would."""
