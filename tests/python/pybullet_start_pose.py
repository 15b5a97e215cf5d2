"""Loads a design's URDF in PyBullet at the start pose written beside it, and reports as
JSON where PyBullet puts each foot against where Strider's model does, the total mass it
read, and where the body is after 2 s standing on a plane with every joint held at its
start angle by its motor (the URDF's effort limit): a second engine's view of the design.

Usage: python3 pybullet_start_pose.py DESIGN.urdf DESIGN.start_pose.json
"""
import json
import math
import sys

import pybullet as p

urdf, pose_file = sys.argv[1], sys.argv[2]
with open(pose_file) as f:
    pose = json.load(f)

p.connect(p.DIRECT)
robot = p.loadURDF(
    urdf,
    basePosition=pose["base_xyz"],
    baseOrientation=p.getQuaternionFromEuler(pose["base_rpy"]),
    flags=p.URDF_USE_INERTIA_FROM_FILE,  # the URDF's inertias, not solid boxes
)
info = [p.getJointInfo(robot, i) for i in range(p.getNumJoints(robot))]
joints = {i[1].decode(): i[0] for i in info}
links = {i[12].decode(): i[0] for i in info}
missing = sorted(set(pose["joints"]) - set(joints))
if missing:
    sys.exit(f"joints of the start pose missing from the URDF as PyBullet reads it: {missing}")
for name, q in pose["joints"].items():
    p.resetJointState(robot, joints[name], q)

feet = []
for foot in pose["feet"]:
    state = p.getLinkState(robot, links[foot["link"]], computeForwardKinematics=True)
    tip, _ = p.multiplyTransforms(state[4], state[5], foot["tip_in_link"], [0, 0, 0, 1])
    feet.append({"link": foot["link"], "pybullet": tip, "model": foot["start_xyz"],
                 "error_m": math.dist(tip, foot["start_xyz"])})
mass = sum(p.getDynamicsInfo(robot, i)[0] for i in range(-1, p.getNumJoints(robot)))

p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE))
p.setGravity(0, 0, -9.81)
for name, q in pose["joints"].items():
    j = joints[name]
    p.setJointMotorControl2(robot, j, p.POSITION_CONTROL, targetPosition=q,
                            force=info[j][10])
for _ in range(2 * 240):
    p.stepSimulation()
position, orientation = p.getBasePositionAndOrientation(robot)
roll, pitch, _ = p.getEulerFromQuaternion(orientation)

print(json.dumps({
    "feet": feet,
    "worst_foot_error_m": max(f["error_m"] for f in feet),
    "mass_kg": mass,
    "start_height_m": pose["base_xyz"][2],
    "height_after_2s_m": position[2],
    "tilt_after_2s_degrees": math.degrees(max(abs(roll), abs(pitch))),
}))
