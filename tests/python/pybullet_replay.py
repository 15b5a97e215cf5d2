"""Replays a design's trial in PyBullet, a second engine, with Strider's gait and drive law,
and reports as JSON what happened: the distance its centre of mass moved forward over the
trial, the energy its joints spent, and whether it stayed up (through the trial and the
window after it) with only its lower legs on the ground.

Everything comes from Strider's own files: the URDF (links, masses, inertias, joints; each
joint's torque limit is its `effort`, its servo gains the `<dynamics>` `spring_stiffness`
and `damping`), the start pose beside it, and a trace of the trial (`strider-worker eval
--trace`), whose `*_target*` columns are the joint targets over each control step. Each
joint is driven by the same law as in Strider: torque = clamp(k (q* - q) - D qdot,
+-effort), recomputed every physics step, applied as a torque (PyBullet's own motors off).
PyBullet applies that torque explicitly, which is stable only while D dt / I < 2 for every
joint: light lower legs need about 4000 Hz (the default; MAX walks the same at 1000 Hz).

Usage: python3 pybullet_replay.py DESIGN.urdf DESIGN.start_pose.json TRACE.csv
           [--hz 4000] [--trial-seconds 5] [--max-tilt 45] [--after-max-tilt 20]
           [--min-height-fraction 0.5] [--friction 0.8] [--cone 1]
           [--contact-stiffness 0 --contact-damping 0]

The contact knobs are for measuring where the engines differ (docs/model.md section 6):
--friction is the robot's coefficient against the ground (Strider's is 0.8); --cone 0 uses
Bullet's pyramid friction instead of its default cone; a --contact-stiffness above 0 (N/m,
with --contact-damping, Ns/m) makes Bullet's contacts soft instead of rigid.
"""
import argparse
import csv
import json
import math
import xml.etree.ElementTree as ET

import pybullet as p

ap = argparse.ArgumentParser()
ap.add_argument("urdf")
ap.add_argument("start_pose")
ap.add_argument("trace")
ap.add_argument("--hz", type=float, default=4000.0)
ap.add_argument("--trial-seconds", type=float, default=5.0)
ap.add_argument("--max-tilt", type=float, default=45.0)
ap.add_argument("--after-max-tilt", type=float, default=20.0)
ap.add_argument("--min-height-fraction", type=float, default=0.5)
ap.add_argument("--friction", type=float, default=0.8)
ap.add_argument("--cone", type=int, choices=[0, 1], default=1)
ap.add_argument("--contact-stiffness", type=float, default=0.0)
ap.add_argument("--contact-damping", type=float, default=0.0)
args = ap.parse_args()

# The servo of every joint, from the URDF.
servo = {}
for joint in ET.parse(args.urdf).getroot().iter("joint"):
    if joint.get("type") != "revolute":
        continue
    dyn, limit = joint.find("dynamics"), joint.find("limit")
    servo[joint.get("name")] = (
        float(dyn.get("spring_stiffness")),
        float(dyn.get("damping")),
        float(limit.get("effort")),
    )

# The targets over each control step, and the control step's length.
with open(args.trace) as f:
    rows = list(csv.DictReader(f))
target_columns = [c for c in rows[0] if "_target" in c]
control_dt = float(rows[1]["time_s"]) - float(rows[0]["time_s"])
targets = [[float(r[c]) for c in target_columns] for r in rows]

with open(args.start_pose) as f:
    pose = json.load(f)

p.connect(p.DIRECT)
p.setGravity(0, 0, -9.81)
dt = 1.0 / args.hz
p.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=1, enableConeFriction=args.cone)
plane = p.createMultiBody(0, p.createCollisionShape(p.GEOM_PLANE))
robot = p.loadURDF(
    args.urdf,
    basePosition=pose["base_xyz"],
    baseOrientation=p.getQuaternionFromEuler(pose["base_rpy"]),
    # Bullet otherwise recomputes each link's inertia from its collision box as if solid:
    # our links are tubes with motors at their joints and the body carries the payload, so
    # that gave a body about twice our moments of inertia (1.9x about pitch and yaw, 2.8x
    # about roll for one elite).
    flags=p.URDF_USE_INERTIA_FROM_FILE,
)
n = p.getNumJoints(robot)
info = [p.getJointInfo(robot, i) for i in range(n)]
index = {i[1].decode(): i[0] for i in info}
link_names = {i[0]: i[12].decode() for i in info}
# Strider's trace lists joints leg by leg in the URDF's leg order: leg{L}_{hip,upper,lower}.
names = sorted(servo, key=lambda s: (int(s[3:s.index("_")]), ["hip", "upper", "lower"].index(s.split("_")[1])))
assert len(names) == len(target_columns), (names, target_columns)
joints = [index[name] for name in names]
for name, q in pose["joints"].items():
    p.resetJointState(robot, index[name], q)
# Friction combines by product in Bullet, by average in rapier (0.8 on every collider).
p.changeDynamics(plane, -1, lateralFriction=1.0, restitution=0.0)
for link in range(-1, n):
    p.changeDynamics(robot, link, lateralFriction=args.friction, restitution=0.0,
                     linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
    if args.contact_stiffness > 0:
        p.changeDynamics(robot, link, contactStiffness=args.contact_stiffness,
                         contactDamping=args.contact_damping)
p.setJointMotorControlArray(robot, joints, p.VELOCITY_CONTROL, forces=[0.0] * len(joints))
gains = [servo[name] for name in names]
masses = [p.getDynamicsInfo(robot, link)[0] for link in range(-1, n)]


def com():
    total, acc = 0.0, [0.0, 0.0, 0.0]
    for link, m in zip(range(-1, n), masses):
        if link < 0:
            at = p.getBasePositionAndOrientation(robot)[0]
        else:
            at = p.getLinkState(robot, link, computeForwardKinematics=True)[0]
        total += m
        acc = [a + m * x for a, x in zip(acc, at)]
    return [a / total for a in acc]


def tilt():
    # The body's up axis is the URDF's z: the third column of its rotation.
    m = p.getMatrixFromQuaternion(p.getBasePositionAndOrientation(robot)[1])
    return math.degrees(math.acos(max(-1.0, min(1.0, m[8]))))


start_height = pose["base_xyz"][2]
start_com = com()
trial_steps = round(args.trial_seconds * args.hz)
total_steps = round(len(rows) * control_dt * args.hz)
per_control = round(control_dt * args.hz)
energy, peak, max_tilt, ended = 0.0, 0.0, 0.0, None
end_com = None
for step in range(total_steps):
    if step == trial_steps:
        end_com = com()
    q_star = targets[min(step // per_control, len(targets) - 1)]
    states = p.getJointStates(robot, joints)
    torques = []
    for (k, d, limit), (q, qd, _, _), target in zip(gains, states, q_star):
        tau = max(-limit, min(limit, k * (target - q) - d * qd))
        torques.append(tau)
        peak = max(peak, abs(tau) / limit)
    p.setJointMotorControlArray(robot, joints, p.TORQUE_CONTROL, forces=torques)
    p.stepSimulation()
    t = (step + 1) * dt
    after = step >= trial_steps
    if not after:
        for tau, (_, qd, _, _) in zip(torques, p.getJointStates(robot, joints)):
            energy += abs(tau * qd) * dt
    a = tilt()
    max_tilt = max(max_tilt, a)
    limit = min(args.max_tilt, args.after_max_tilt) if after else args.max_tilt
    if a > limit:
        ended = {"how": "tilted", "at_time": t, "degrees": a}
        break
    if p.getBasePositionAndOrientation(robot)[0][2] < args.min_height_fraction * start_height:
        ended = {"how": "sank", "at_time": t}
        break
    touching = {c[3] for c in p.getContactPoints(robot, plane) if c[8] <= 0.0}
    dragged = [link_names.get(l, "body") for l in touching if not link_names.get(l, "body").endswith("_lower")]
    if dragged:
        ended = {"how": "dragged", "at_time": t, "part": dragged[0]}
        break
if end_com is None:
    end_com = com()

print(json.dumps({
    "upright": ended is None,
    "ended": ended,
    "distance_m": end_com[0] - start_com[0] if ended is None or ended["at_time"] > args.trial_seconds else None,
    "energy_j": energy,
    "max_tilt_degrees": max_tilt,
    "peak_torque_ratio": peak,
    "hz": args.hz,
}))
