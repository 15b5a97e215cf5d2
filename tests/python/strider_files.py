"""Reading what Strider exports, for the scripts that replay its designs in other engines
(`pybullet_replay.py` here, `bench/mujoco-max.py`): one reading, so the scripts stay in step
if a file's layout changes.

- The URDF (`strider-worker urdf`): each revolute joint's servo, its gains in `<dynamics>`
  (`spring_stiffness` k, `damping` D) and its torque limit in `<limit effort>`.
- The trace (`strider-worker eval --trace`): one row a control step, `time_s` and each
  joint's `<joint>_target` in leg order, leg{L}_{hip,upper,lower}.
- The start pose (written beside the URDF): `base_xyz`, `base_rpy` and each joint's angle.
"""
import csv
import json
import xml.etree.ElementTree as ET


def servos(urdf_root):
    """Each revolute joint's servo, by name: (stiffness Nm/rad, damping Nms/rad, effort Nm)."""
    servo = {}
    for joint in urdf_root.iter("joint"):
        if joint.get("type") != "revolute":
            continue
        dyn, limit = joint.find("dynamics"), joint.find("limit")
        servo[joint.get("name")] = (
            float(dyn.get("spring_stiffness")),
            float(dyn.get("damping")),
            float(limit.get("effort")),
        )
    return servo


def trace_order(joint_names):
    """The joints in the trace's order: leg by leg, hip, upper, lower."""
    return sorted(joint_names, key=lambda s: (int(s[3:s.index("_")]),
                                              ["hip", "upper", "lower"].index(s.split("_")[1])))


class Trace:
    """The targets of each control step, and the control step's length in seconds."""

    def __init__(self, path):
        with open(path) as f:
            self.rows = list(csv.DictReader(f))
        self.target_columns = [c for c in self.rows[0] if "_target" in c]
        self.control_dt = float(self.rows[1]["time_s"]) - float(self.rows[0]["time_s"])
        self.targets = [[float(r[c]) for c in self.target_columns] for r in self.rows]


def read_urdf(path):
    """The URDF's root element."""
    return ET.parse(path).getroot()


def read_start_pose(path):
    """The start pose as a dict: `base_xyz` (m), `base_rpy` (rad) and `joints`, each
    joint's angle (rad) by name."""
    with open(path) as f:
        return json.load(f)
