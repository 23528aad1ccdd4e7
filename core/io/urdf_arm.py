"""An arm model from a URDF (`read_urdf_arm`): the chain of revolute joints from the root link to
the tip, as an exact standard DH table with a base and a tool transform
(`handeye.geometry.dh_conversion.dh_from_axes`), so that a kinematic calibration reads the robot
description a ROS cell already has.

The URDF is parsed by `yourdfpy` (maintained, MIT; an optional dependency: ``pip install
handeye[urdf]``), without meshes. The chain: from the root link (no joint's child) follow the
joints; revolute and continuous joints are the arm's, fixed joints are folded into the transforms
between them. Where the tree branches, the branch that holds revolute joints is followed (an error
when several do); after the last revolute joint, fixed joints are followed while they do not branch,
so the tip is e.g. ``tool0`` of a ROS-Industrial description (else the last joint's child link).
Prismatic, planar, floating joints and mimic joints are refused. Lengths in metres, angles in
radians, as URDF has them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from handeye.base.errors import InputError
from handeye.geometry.dh_conversion import dh_from_axes

#: the joint types of the arm, and those folded into the transforms between them
MOVING = ("revolute", "continuous")
FIXED = ("fixed",)


def read_urdf_arm(path: str | Path) -> dict:
    """The fields of the `handeye.io.arm_files.ArmModel` of the URDF at `path` (module
    docstring): the DH table (m, angles shown in deg), its `base` and `tool` transforms, the
    joints' names and `frames` (root link, tip link). InputError naming the file for anything else."""
    path = Path(path)
    where = f"arm file {str(path)!r}"
    try:
        import yourdfpy
    except ImportError:
        raise InputError(f"{where} is a URDF: reading it needs the package yourdfpy (pip install 'handeye[urdf]'), "
                         "or give the arm's standard DH table as YAML (docs/formats.md, 'Arm models')") from None
    try:
        urdf = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                                  build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as exc:  # noqa: BLE001 - lxml / yourdfpy raise many kinds on a bad file
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise InputError(f"{where} could not be read as a URDF: {reason}") from None
    joints = list(urdf.robot.joints)
    if not joints:
        raise InputError(f"{where} holds no joints; an arm needs its chain of revolute joints")
    root, by_parent = _tree(joints, where)
    roots = [root]

    def moving_below(link: str) -> bool:
        return any(j.type not in FIXED or moving_below(j.child) for j in by_parent.get(link, ()))

    link, T = roots[0], np.eye(4)
    points, directions, names = [], [], []
    while True:
        options = by_parent.get(link, [])
        ahead = [j for j in options if j.type not in FIXED or moving_below(j.child)]
        if len(ahead) > 1:
            raise InputError(f"{where}: link {link!r} branches into several chains of revolute joints "
                             f"({', '.join(j.name for j in ahead)}); give the arm's DH table as YAML")
        if not ahead:
            break
        j = ahead[0]
        if j.type not in MOVING + FIXED:
            raise InputError(f"{where}: joint {j.name!r} is {j.type}; only revolute (and continuous) joints are read")
        if j.mimic is not None:
            raise InputError(f"{where}: joint {j.name!r} mimics another joint; mimic joints are not read")
        T = T @ (np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float))
        if j.type in MOVING:
            axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
            if not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-12:
                raise InputError(f"{where}: joint {j.name!r} has axis {axis.tolist()}; expected a non-zero direction")
            points.append(T[:3, 3].copy())
            directions.append(T[:3, :3] @ axis / np.linalg.norm(axis))
            names.append(j.name)
        link = j.child
    while len(by_parent.get(link, [])) == 1 and by_parent[link][0].type in FIXED:  # tool0 after flange
        j = by_parent[link][0]
        T = T @ (np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float))
        link = j.child
    if len(names) < 2:
        raise InputError(f"{where}: {len(names)} revolute joint(s) from {roots[0]!r}; an arm has two or more")
    if not np.all(np.isfinite(T)):
        raise InputError(f"{where}: a joint origin holds NaN or inf")
    arm, base, tool = dh_from_axes(np.array(points), np.array(directions), T)
    return {"dh": arm, "unit": "m", "names": tuple(names), "angle_unit": "deg", "source": str(path), "base": base,
            "tool": tool, "frames": (roots[0], link)}


def _tree(joints: list, where: str) -> tuple[str, dict[str, list]]:
    """(the root link, the joints below each link) of a URDF's joints, checked to be a tree: one
    root, every link the child of one joint at most, every joint reachable from the root (a loop
    of joints, fixed or not, is refused instead of followed for ever)."""
    parents: dict[str, list[str]] = {}
    for j in joints:
        parents.setdefault(j.child, []).append(j.name)
    twice = {link: names for link, names in parents.items() if len(names) > 1}
    if twice:
        link, names = next(iter(twice.items()))
        raise InputError(f"{where}: link {link!r} is the child of joints {', '.join(map(repr, names))}; a URDF's joints "
                         "form a tree (one parent joint per link)")
    roots = sorted({j.parent for j in joints} - set(parents))
    by_parent: dict[str, list] = {}
    for j in joints:
        by_parent.setdefault(j.parent, []).append(j)
    reached, stack = set(), list(roots)
    while stack:
        for j in by_parent.get(stack.pop(), ()):
            if j.name not in reached:
                reached.add(j.name)
                stack.append(j.child)
    loop = [j.name for j in joints if j.name not in reached]
    if loop:
        raise InputError(f"{where}: joints {', '.join(map(repr, loop[:6]))} form a loop (a link is its own ancestor); a "
                         "URDF's joints form a tree")
    if len(roots) != 1:
        raise InputError(f"{where}: expected one root link (a tree of joints), found {roots or 'none'}")
    return roots[0], by_parent


def urdf_pose(path: str | Path, q: np.ndarray) -> np.ndarray:
    """T_root_tip at joint values q (n,) rad of the URDF at `path`, by yourdfpy's own forward
    kinematics (tests compare the DH model with it)."""
    import yourdfpy

    model = read_urdf_arm(path)
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False)
    urdf.update_cfg(dict(zip(model["names"], np.asarray(q, dtype=float))))
    return urdf.get_transform(model["frames"][1], model["frames"][0])


__all__ = ["read_urdf_arm", "urdf_pose"]
