"""From a cell's recordings to what a user keeps.

`calibration.calibrate` (``handeye.calibrate``) runs a `cell.Cell` (what a cell recorded and
how to read it; `cell_file` its YAML form): `reading` and `stations` (`image_stations` for board
images) pair the recordings into stations, `solving` holds the default solver and time limit,
`result.CalibrationResult` carries the answer with its `frames`, checks and `exports` (JSON,
YAML, ROS 2, URDF, xacro). The quality report: `quality_report` collects a run into plain data;
`report_layout` says what the report holds; `report_render` writes it as HTML or markdown;
`report_plots` and `report_images` draw its figures.
"""
