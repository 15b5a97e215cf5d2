"""MAX's trial in MuJoCo, timed: the peer a user would pick instead, and a calibration of
the machine a benchmark ran on (machines here differ by 2x; BENCHMARKS.md compares figures
only from one machine, and this converts between them).

The design as Strider exports it (`strider-worker urdf designs/max.json --out max.urdf`,
which writes max.start_pose.json beside it) on a floor of friction 0.8, each joint driven
by the servo law of the URDF (torque = clamp(k (q* - q) - D qdot, +-effort), `<dynamics>`
and `<limit effort>`) toward the targets of Strider's trace (`strider-worker eval
designs/max.json --trace max.csv`), for 6 s (the trace's length: the 5-s trial and its 1-s
window) at 240 Hz. Reports, best of --repeats, the time inside `mj_step` alone (the
controller's Python left out) and with it.

Usage: python3 bench/mujoco-max.py max.urdf max.start_pose.json max.csv [--hz 240]
           [--repeats 5]
Needs `pip install mujoco`.
"""
import argparse
import sys
import time
from pathlib import Path

import mujoco

# Strider's files read as the PyBullet replay reads them.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "python"))
from strider_files import Trace, read_start_pose, read_urdf, servos, trace_order  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("urdf")
ap.add_argument("start_pose")
ap.add_argument("trace")
ap.add_argument("--hz", type=float, default=240.0)
ap.add_argument("--repeats", type=int, default=5)
args = ap.parse_args()

spec = mujoco.MjSpec.from_file(args.urdf)
# MuJoCo's URDF import fixes the root link to the world: free it, and add the floor.
spec.worldbody.first_body().add_freejoint()
spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[50, 50, 0.1],
                        friction=[0.8, 0.005, 0.0001])
spec.option.timestep = 1.0 / args.hz
model = spec.compile()

servo = servos(read_urdf(args.urdf))
names = trace_order(servo)
qpos = [model.jnt_qposadr[model.joint(n).id] for n in names]
dofs = [model.jnt_dofadr[model.joint(n).id] for n in names]
gains = [servo[n] for n in names]
trace = Trace(args.trace)
rows, targets = trace.rows, trace.targets
assert len(names) == len(trace.target_columns), (names, trace.target_columns)
pose = read_start_pose(args.start_pose)
per_control = round(args.hz * trace.control_dt)
steps = per_control * len(rows)


def trial():
    data = mujoco.MjData(model)
    data.qpos[0:3] = pose["base_xyz"]
    data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
    for name, at in zip(names, qpos):
        data.qpos[at] = pose["joints"][name]
    mujoco.mj_forward(model, data)
    start_x, stepping = data.qpos[0], 0.0
    began = time.perf_counter()
    for step in range(steps):
        target = targets[min(step // per_control, len(targets) - 1)]
        for (k, damping, limit), q, v, q_star in zip(gains, qpos, dofs, target):
            tau = k * (q_star - data.qpos[q]) - damping * data.qvel[v]
            data.qfrc_applied[v] = max(-limit, min(limit, tau))
        t = time.perf_counter()
        mujoco.mj_step(model, data)
        stepping += time.perf_counter() - t
    return stepping, time.perf_counter() - began, data.qpos[0] - start_x, data.qpos[2]


runs = [trial() for _ in range(args.repeats)]
stepping = min(r[0] for r in runs)
whole = min(r[1] for r in runs)
_, _, forward, height = runs[-1]
print(f"MuJoCo {mujoco.__version__}, {args.hz:g} Hz, {steps} steps (best of {args.repeats}): "
      f"{stepping * 1e3:.1f} ms in mj_step ({stepping / steps * 1e6:.1f} us a step), "
      f"{whole * 1e3:.1f} ms with the servo loop in Python; "
      f"the body {forward:.2f} m forward, {height:.2f} m up at the end")
