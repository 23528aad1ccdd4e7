"""From images to poses: calibration boards, their detection and rendering, camera intrinsics,
board poses (PnP) and the image observations that the reprojection-error solver refines on.

Heavy work (OpenCV) is imported by the submodules only; importing this package costs nothing.
"""
