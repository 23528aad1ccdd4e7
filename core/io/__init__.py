"""Reading and writing what a cell records, without trusting it.

The data files of a problem (``load_file``, ``load_data``, ``save_data``, ``from_poses``: NPZ
and JSON, `data_files`), the robot's and camera's pose files in vendors' formats
(`pose_formats`, `pose_readers`), ROS bags (`bag_readers`), NPZ archives (`npz`), YAML and JSON
documents (`input_files`), output files written whole (`output_files`), and the bundled examples
(`examples`).
"""

from handeye.io.data_files import (
    DEFAULT_PAIRING,
    METADATA_KEYS,
    PAIRINGS,
    POSE_FIELDS,
    SETUPS,
    UNITS,
    PoseFile,
    from_poses,
    load_data,
    load_file,
    save_data,
    station_readers,
    supported_extensions,
)

__all__ = ["DEFAULT_PAIRING", "METADATA_KEYS", "PAIRINGS", "POSE_FIELDS", "SETUPS", "UNITS", "PoseFile", "from_poses",
           "load_data", "load_file", "save_data", "station_readers", "supported_extensions"]
