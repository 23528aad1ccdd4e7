"""Time-stamped pose streams: read, resample, estimate the clock offset, select motion, pair.

A tracker or camera records poses at its rate, the robot at its own, with clocks that differ by
an unknown constant offset. `pair_streams(robot, camera, setup=...)` turns the two streams
(`handeye.io.pose_readers.PoseStack` with stamps, from pose files or from ROS bags via
`handeye.io.bag_readers.read_bag_poses`) into the stations of a calibration:

- the clock offset, t_robot = t_camera + offset (`offset`): cross-correlation of the angular
  speeds, refined by minimising the residuals of A_i X = Y B_i, with a 1-sigma;
- the robot interpolated at each camera stamp + offset, SLERP / linear, never extrapolated, no
  dropout wider than max_gap bridged (`resample`);
- static stations dropped, at most max_pairs well-spread ones kept (`selection`).

docs/streams.md is the user's guide; ``handeye calibrate --match interpolate`` the command.
"""

from __future__ import annotations

from handeye.geometry.resample import Resampled, angular_speed, resample_poses
from handeye.streams.offset import (
    CoarseOffset,
    OffsetEstimate,
    coarse_offset,
    refine_offset,
)
from handeye.streams.pairing import MAX_OFFSET, StreamPairs, pair_streams
from handeye.streams.selection import MAX_PAIRS, MIN_ANGULAR_SPEED
from handeye.streams.timeline import checked_stream, default_max_gap

__all__ = [
    "MAX_OFFSET", "MAX_PAIRS", "MIN_ANGULAR_SPEED", "CoarseOffset", "OffsetEstimate", "Resampled",
    "StreamPairs", "angular_speed", "checked_stream", "coarse_offset", "default_max_gap", "pair_streams",
    "refine_offset", "resample_poses",
]
