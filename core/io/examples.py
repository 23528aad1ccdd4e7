"""Bundled example data sets (files in handeye/data/, made by tools/make_example_data.py).

- ``eth-robot-arm``: REAL eye-in-hand data, 50 pose pairs of the ETH Zurich ASL ``robot_arm``
  recording (Furrer et al., FSR 2017; BSD-3-Clause, Copyright (c) 2017 ETHZ ASL), metres.
- ``simulated``: the paper's simulation (Pan et al., T-ASE 2022, Sec. IV-A), 16 pairs with
  noise on B, millimetres, with the true X and Y.

``handeye solve --example [NAME]`` solves one of these.

Image example (a folder, not a pose file): ``image_example_dir()`` is ``handeye/data/rct_circle_grid/``,
REAL eye-in-hand images of a 10x10 circle grid with one robot pose file per image (ROS-Industrial's
industrial_calibration ``test_set_10x10``; Apache-2.0, images converted to grayscale), for
``handeye calibrate --images`` (docs/images.md).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from handeye.framework.errors import UnknownPluginError
from handeye.io.data_files import load_file

#: example name -> file in handeye/data/
EXAMPLES: dict[str, str] = {
    "eth-robot-arm": "eth_robot_arm.json",
    "simulated": "simulated_paper.json",
}
DEFAULT_EXAMPLE = "eth-robot-arm"
#: the problem whose data the bundled pose examples are: AX=YB pairs (A, B), one per station
EXAMPLE_PROBLEM = "axyb"


def list_examples() -> list[str]:
    """Names of the bundled examples."""
    return sorted(EXAMPLES)


def load_example(name: str = DEFAULT_EXAMPLE) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None, dict[str, str]]:
    """``(data, truth, metadata)`` of a bundled example (all ``axyb`` data: A, B (m, 4, 4)).

    truth is None for real data; metadata holds ``units``, ``setup``, ``description``,
    ``source`` and ``license``. Raises UnknownPluginError (listing the names) for an unknown name.
    """
    if name not in EXAMPLES:
        raise UnknownPluginError("example", name, EXAMPLES)
    resource = resources.files("handeye").joinpath("data", EXAMPLES[name])
    with resources.as_file(resource) as path:
        pose_file = load_file(path, problem=EXAMPLE_PROBLEM)
    return pose_file.data, pose_file.truth, pose_file.metadata


#: folder of the bundled image example in handeye/data/
IMAGE_EXAMPLE = "rct_circle_grid"


def image_example_dir() -> Path:
    """The folder of the bundled image example: ``images/`` (15 PNGs, 640 x 480, board
    ``circlegrid:10x10:25.4mm``), ``poses/`` (``N.yaml``: x, y, z in metres, qx, qy, qz, qw of
    T_base_flange, eye-in-hand), ``cal_data.yaml`` (nominal intrinsics only), ``README.md`` and
    ``LICENSE`` (Apache-2.0). A path on disk (the package is installed as files)."""
    return Path(str(resources.files("handeye").joinpath("data", IMAGE_EXAMPLE)))
