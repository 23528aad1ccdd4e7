"""Calibration problems shipped with handeye (each module is one problem plugin)."""
