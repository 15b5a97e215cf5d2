"""Replays many designs in PyBullet (pybullet_replay.py beside this file) and reports how
well the two engines agree: for each design Strider's outcome, then PyBullet's replay of
the same URDF, start pose, gait targets and drive law; at the end, how many of the designs
Strider ran to the end stay upright in PyBullet, and how many of those are within 10 % of
Strider's distance. Each line carries both engines' feet figures (`our_feet`, and
`pybullet.feet`: slip, share of forward travel along the ground, duty factor). A replay
that ends tipped past the window's tilt limit (20 degrees) is run again with the limit at
45 (`pybullet_run_on`): `fell` says whether it went on to fall, `max_tilt_degrees` how far
it leaned; the first replay's reading, just past 20, is only where it stopped.

Usage: python3 tests/python/pybullet_agreement.py GENOMES.json [--worker PATH] [--hz 4000]
           [--scheme static|genome] [--experiment FILE] [--out DIR]
           [--friction 0.8] [--cone 1]
--friction and --cone go to every replay (pybullet_replay.py says what they do): with
--friction 0.6 the 40 fittest elites of docs/model.md section 6 agree within its bars.
GENOMES.json: `strider-coordinator export --format json` (every run's elites) or a JSON
array of genomes. Prints one JSON line per design, then a summary line.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

here = os.path.dirname(os.path.abspath(__file__))
ap = argparse.ArgumentParser()
ap.add_argument("genomes")
ap.add_argument("--worker", default="target/release/strider-worker")
ap.add_argument("--hz", type=float, default=4000.0)
ap.add_argument("--scheme", default="static")
ap.add_argument("--experiment")
ap.add_argument("--out")
ap.add_argument("--friction", type=float, default=0.8)
ap.add_argument("--cone", type=int, choices=[0, 1], default=1)
args = ap.parse_args()

with open(args.genomes) as f:
    data = json.load(f)
if isinstance(data, dict):
    genomes = [e["genome"] for run in data["runs"] for e in run["elites"]]
else:
    genomes = data
out = args.out or tempfile.mkdtemp(prefix="pybullet-agreement-")
os.makedirs(out, exist_ok=True)



def replay(base, *extra):
    """pybullet_replay.py's report on the design written at `base`, with this run's
    settings and `extra` arguments."""
    return json.loads(subprocess.run(
        [sys.executable, os.path.join(here, "pybullet_replay.py"), base + ".urdf",
         base + ".start_pose.json", base + ".csv", "--hz", str(args.hz),
         "--friction", str(args.friction), "--cone", str(args.cone), *extra],
        check=True, capture_output=True, text=True).stdout)


completed = upright = close = 0
for i, g in enumerate(genomes):
    base = os.path.join(out, f"d{i}")
    with open(base + ".json", "w") as f:
        json.dump(g, f)
    extra = ["--experiment", args.experiment] if args.experiment else []
    ours = json.loads(subprocess.run(
        [args.worker, "eval", base + ".json", "--scheme", args.scheme, "--json",
         "--trace", base + ".csv", *extra],
        check=True, capture_output=True, text=True).stdout)
    subprocess.run([args.worker, "urdf", base + ".json", "--out", base + ".urdf"],
                   check=True, capture_output=True)
    row = {"design": i, "ours": ours["outcome"], "our_distance_m": None}
    stats = ours.get("stats")
    if stats:
        completed += 1
        row["our_distance_m"] = stats["distance"]
        row["our_energy_j"] = stats["energy"]
        row["our_feet"] = stats.get("gait")
        theirs = replay(base)
        row["pybullet"] = theirs
        ended = theirs.get("ended") or {}
        if ended.get("how") == "tilted" and ended["degrees"] < 45.0:
            # A replay stops on the step the tilt first passes the window's limit, so its
            # reading is always just past 20 degrees: run on to 45 to tell a fall from a
            # lean that comes back (docs/model.md section 6, "A tilt read just past 20°").
            on = replay(base, "--after-max-tilt", "45")
            row["pybullet_run_on"] = {"fell": not on["upright"], "ended": on["ended"],
                                      "max_tilt_degrees": on["max_tilt_degrees"]}
        if theirs["upright"]:
            upright += 1
            if abs(theirs["distance_m"] - stats["distance"]) <= 0.1 * abs(stats["distance"]):
                close += 1
    else:
        row["why"] = ours.get("reason")
    print(json.dumps(row), flush=True)

print(json.dumps({"designs": len(genomes), "completed_in_strider": completed,
                  "upright_in_pybullet": upright, "within_10_percent": close, "hz": args.hz,
                  "friction": args.friction, "cone": args.cone}))
