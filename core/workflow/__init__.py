"""From a solve to what a user keeps: the quality report (`quality_report` collects a run into
plain data; `report_layout` says what the report holds; `report_render` writes it as HTML or
markdown; `report_plots` and `report_images` draw its figures).
"""
