"""Which stations to record: planned stations, predicted 1-sigma and what to record next
(`plan`, `next_stations`; docs/planning.md)."""
