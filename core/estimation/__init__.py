"""Estimation shared by every problem: the on-manifold least-squares engine (`nlls`), weights
and noise models (`whitening`, `robust`, `noise`, `noise_sources`), the camera's unknown scale
(`camera_scale`; one per camera of a cell: `camera_scales`), Kronecker linear systems
(`kronecker`), SO(3) relaxations and their certificates (`so3_relaxation`, `rotation_cost`,
`trust_region`).
"""
