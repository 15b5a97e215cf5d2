"""Replays a design's trial in PyBullet, a second engine, with Strider's gait and drive law,
and reports as JSON what happened: the distance its centre of mass moved forward over the
trial, the energy its joints spent, whether it stayed up (through the trial and the
window after it) with only its lower legs on the ground and, through the trial, no two of
its parts touching (but those joined by a hinge), and how its feet stepped over the trial,
measured as Strider measures them (docs/model.md section 6, "Feet that step"): the
distance a foot slid while on the ground (mean over feet), the share of the feet's forward
travel within 3 cm of the ground, and the duty factor; `peak_torque_ratio` is the largest
torque a joint received over its limit (the URDF's `effort`), 1.0 when a joint was held at
its limit. On stderr, a line a person reads: the two engines side by side over the trial
(the body's forward travel and the energy, both of which the trace carries for Strider) and
whether they agree within 10 %.

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
           [--contact-stiffness 0 --contact-damping 0] [--self-contact 1]

The contact knobs are for measuring where the engines differ (docs/model.md section 6):
--friction is the robot's coefficient against the ground (Strider's is 0.8); --cone 0 uses
Bullet's pyramid friction instead of its default cone; a --contact-stiffness above 0 (N/m,
with --contact-damping, Ns/m) makes Bullet's contacts soft instead of rigid; --self-contact 0
lets the robot's parts pass through each other (Strider's collide, except across a hinge,
and a self-contact ends the trial).
"""
import argparse
import json
import math
import sys

import pybullet as p

from strider_files import Trace, read_start_pose, read_urdf, servos, trace_order

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
ap.add_argument("--self-contact", type=int, choices=[0, 1], default=1)
args = ap.parse_args()

# The URDF, parsed once: the servos here, the feet's tube sizes below.
urdf_root = read_urdf(args.urdf)
servo = servos(urdf_root)
# The targets over each control step, and the control step's length.
trace = Trace(args.trace)
rows, target_columns, control_dt, targets = (
    trace.rows, trace.target_columns, trace.control_dt, trace.targets)
pose = read_start_pose(args.start_pose)

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
    flags=p.URDF_USE_INERTIA_FROM_FILE
    # Strider's robot collides with itself except across a hinge, and a self-contact ends
    # its trial.
    | (p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
       if args.self_contact else 0),
)
n = p.getNumJoints(robot)
info = [p.getJointInfo(robot, i) for i in range(n)]
index = {i[1].decode(): i[0] for i in info}
link_names = {i[0]: i[12].decode() for i in info}
names = trace_order(servo)
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


# The feet: the tip of each lower leg (its link frame's +z, at the tube's length), less half
# the tube's width, as worker/src/sim/feet.rs takes it.
GROUND_CLEARANCE = 0.03
feet = []
for link, name in sorted(link_names.items()):
    if name.endswith("_lower"):
        box = urdf_root.find(f"link[@name='{name}']/collision/geometry/box")
        size = [float(x) for x in box.get("size").split()]
        feet.append({"link": link, "length": size[2], "half_width": 0.5 * size[0],
                     "slip": 0.0, "forward": 0.0, "forward_low": 0.0, "steps_down": 0})


def foot_position(foot):
    state = p.getLinkState(robot, foot["link"], computeForwardKinematics=True)
    m = p.getMatrixFromQuaternion(state[5])
    at = [state[4][i] + m[3 * i + 2] * foot["length"] for i in range(3)]
    at[2] -= foot["half_width"]
    return at


def tilt():
    # The body's up axis is the URDF's z: the third column of its rotation.
    m = p.getMatrixFromQuaternion(p.getBasePositionAndOrientation(robot)[1])
    return math.degrees(math.acos(max(-1.0, min(1.0, m[8]))))


start_height = pose["base_xyz"][2]
start_com = com()
trial_steps = round(args.trial_seconds * args.hz)
total_steps = round(len(rows) * control_dt * args.hz)
per_control = round(control_dt * args.hz)
energy, peak, max_tilt, ended, feet_steps = 0.0, 0.0, 0.0, None, 0
for foot in feet:
    foot["at"], foot["down"] = foot_position(foot), False
end_com = None
start_body_x = p.getBasePositionAndOrientation(robot)[0][0]
end_body_x = None
for step in range(total_steps):
    if step == trial_steps:
        end_com = com()
        end_body_x = p.getBasePositionAndOrientation(robot)[0][0]
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
    # As Strider, per step: contacts that end the trial, then the feet, then the tilt and
    # height. Two parts touch while they overlap or the engine pushes them apart (rapier
    # holds a pressed part a hair short of what it presses on).
    # After the trial only falls count, as in Strider (a self-contact then changes no figure).
    if args.self_contact and not after:
        own = [c for c in p.getContactPoints(robot, robot) if c[8] <= 0.0 or c[9] > 0.0]
        if own:
            parts = sorted({link_names.get(own[0][3], "body"), link_names.get(own[0][4], "body")})
            ended = {"how": "self_contact", "at_time": t, "parts": parts}
            break
    contacts = p.getContactPoints(robot, plane)
    touching = {c[3] for c in contacts if c[8] <= 0.0 or c[9] > 0.0}
    dragged = [link_names.get(l, "body") for l in touching if not link_names.get(l, "body").endswith("_lower")]
    if dragged:
        ended = {"how": "dragged", "at_time": t, "part": dragged[0]}
        break
    if not after:
        feet_steps += 1
        for foot in feet:
            now, down = foot_position(foot), foot["link"] in touching
            dx, dy = now[0] - foot["at"][0], now[1] - foot["at"][1]
            if foot["down"] and down:
                foot["slip"] += math.hypot(dx, dy)
            if dx > 0.0:
                foot["forward"] += dx
                if min(now[2], foot["at"][2]) < GROUND_CLEARANCE:
                    foot["forward_low"] += dx
            foot["steps_down"] += down
            foot["at"], foot["down"] = now, down
    a = tilt()
    max_tilt = max(max_tilt, a)
    limit = min(args.max_tilt, args.after_max_tilt) if after else args.max_tilt
    if a > limit:
        ended = {"how": "tilted", "at_time": t, "degrees": a}
        break
    if p.getBasePositionAndOrientation(robot)[0][2] < args.min_height_fraction * start_height:
        ended = {"how": "sank", "at_time": t}
        break
if end_com is None:
    end_com = com()
    end_body_x = p.getBasePositionAndOrientation(robot)[0][0]
forward = sum(f["forward"] for f in feet)

print(json.dumps({
    "upright": ended is None,
    "ended": ended,
    "distance_m": end_com[0] - start_com[0] if ended is None or ended["at_time"] > args.trial_seconds else None,
    "energy_j": energy,
    "max_tilt_degrees": max_tilt,
    "peak_torque_ratio": peak,
    # Over the trial (or up to where it ended), as Strider's `stats.gait` has them.
    "feet": {
        "foot_slip_m": sum(f["slip"] for f in feet) / max(1, len(feet)),
        "low_forward_share": sum(f["forward_low"] for f in feet) / forward if forward > 0 else 0.0,
        "duty_factor": sum(f["steps_down"] for f in feet) / max(1, len(feet)) / max(1, feet_steps),
    },
    "hz": args.hz,
}))

# For a person: Strider's figures over the trial from its trace (the row at the trial's
# end; the trace's body x is forward from the start pose, as PyBullet's is here), against
# PyBullet's.
ours = next((r for r in rows if abs(float(r["time_s"]) - args.trial_seconds) < 0.5 * control_dt), None)
trial_done = ended is None or ended["at_time"] > args.trial_seconds
if ours is None:
    print(f"pybullet ({args.hz:g} Hz): the trace ends before {args.trial_seconds:g} s, so "
          "Strider's trial ended early: nothing to compare", file=sys.stderr)
else:
    our_x, our_energy = float(ours["x_forward_m"]), float(ours["energy_J"])
    their_x = end_body_x - start_body_x

    def rel(theirs, mine):
        return f"{100.0 * (theirs - mine) / abs(mine):+.1f} %" if mine else "n/a"

    # The body frame's travel, which both traces carry; `eval`'s distance and the JSON's
    # distance_m are the centre of mass's, a few centimetres apart.
    print(f"strider (the trace, over the {args.trial_seconds:g}-s trial): body forward "
          f"{our_x:.3f} m (the body frame; eval's distance is the centre of mass's), "
          f"energy {our_energy:.1f} J", file=sys.stderr)
    how = "upright through the trial and the window" if ended is None else (
        f"{ended['how']} at {ended['at_time']:.2f} s")
    print(f"pybullet ({args.hz:g} Hz): {how}; body forward {their_x:.3f} m "
          f"({rel(their_x, our_x)}), energy {energy:.1f} J ({rel(energy, our_energy)}); "
          f"peak torque {peak:.2f} of the limit", file=sys.stderr)
    span = float(rows[-1]["time_s"])
    # The bar of pybullet_agreement.py and docs/model.md section 6: upright, and the
    # distance within 10 %. Strider's own verdict (the brief, its window) is `eval`'s.
    if ended is not None:
        verdict = f"the engines differ: in PyBullet the robot {how} (Strider's trace runs {span:.2f} s)"
    elif trial_done and our_x != 0.0 and abs(their_x - our_x) <= 0.1 * abs(our_x):
        verdict = (f"the engines agree: in PyBullet upright through the trace's {span:.2f} s, "
                   "the distance within 10 % of Strider's")
    else:
        verdict = "the engines differ: the distance more than 10 % from Strider's"
    print(verdict, file=sys.stderr)
