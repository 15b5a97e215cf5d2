"""Where a STATIC or GENOME run's simulation went: each candidate's trials rebuilt from its
stored outcome and the run's settings, and their physics steps summed by outcome and by
the trial's role (the run's trial, its stay-up window, the confirming trials on the
floors of `[trial] friction_margin`, the confirming trial at the finer step of
`[trial] confirm_substeps_factor`). docs/model.md section 6 says what each trial is.

An estimate, from the outcomes alone: it counts the trials the search needed in the order
it tries them (the run's trial, then the grippier floor, the slipperier floor, the finer
step; the first refusal ends it), not the ones an idle thread ran ahead and dropped, and it
prices every physics step alike, though a robot with more legs costs more a step
(BENCHMARKS.md, "Where the full-size run's time goes", compares it with the run's pace).
ES runs are not covered: each candidate there is many controllers' trials.

Usage: python3 bench/run-cost-split.py RUN.db [--generations FIRST LAST]
"""
import argparse
import collections
import json
import sqlite3
import sys
import tomllib

ap = argparse.ArgumentParser()
ap.add_argument("db")
ap.add_argument("--generations", nargs=2, type=int, metavar=("FIRST", "LAST"))
args = ap.parse_args()

db = sqlite3.connect(f"file:{args.db}?mode=ro", uri=True)
experiment = tomllib.loads(db.execute("SELECT definition FROM experiment").fetchone()[0])
schemes = {s for (s,) in db.execute("SELECT DISTINCT scheme FROM runs")}
if "es" in schemes:
    sys.exit("run-cost-split.py: an ES run's candidates are many trials each; not covered")

# The defaults of common/src/experiment/mod.rs, for a definition that leaves a key out.
run = {"trial_seconds": 5.0, "control_hz": 30.0, "physics_substeps": 8, **experiment.get("run", {})}
trial = {
    "upright_after_seconds": 1.0,
    "upright_after_feasible_seconds": 15.0,
    "confirm_substeps_factor": 2,
    "confirm_substeps_upright_seconds": 1.0,
    "friction_margin": 0.25,
}
trial.update(experiment.get("trial", {}))
if "confirm_substeps_upright_seconds" not in experiment.get("trial", {}):
    trial.pop("confirm_substeps_upright_seconds")
steps_per_second = run["control_hz"] * run["physics_substeps"]
length = run["trial_seconds"]
short = trial["upright_after_seconds"]
long = max(trial["upright_after_feasible_seconds"], short)
# The finer step's own window (`confirm_substeps_upright_seconds`). A database written
# before that setting (2026-12-02) stores no such key: its finer step held the long window.
finer_window = max(trial.get("confirm_substeps_upright_seconds", long), short)
floors = trial["friction_margin"] > 0
factor = trial["confirm_substeps_factor"]
more = round(run.get("friction", 0.8) * (1 + trial["friction_margin"]), 6)

# Seconds simulated, by role; a finer-step second counts `factor` run-step seconds.
by_outcome = collections.defaultdict(lambda: collections.Counter())
count = collections.Counter()


def confirmed_in_full(cost):
    if floors:
        cost["floors"] += 2 * (length + long)
    if factor > 1:
        cost["finer step"] += factor * (length + finer_window)


query = "SELECT kind, outcome FROM candidates"
params = ()
if args.generations:
    query += " WHERE generation BETWEEN ? AND ?"
    params = tuple(args.generations)
for kind, text in db.execute(query, params):
    o = json.loads(text)
    cost = collections.Counter()
    if kind == "rejected":
        if o.get("stats") is None:
            label = "rejected before its trial"
        else:
            label = "too slow (its trial and the short window)"
            cost["run's trial"] += length
            cost["run's window"] += short
    elif kind == "valid":
        cost["run's trial"] += length
        if o.get("outranked"):
            label = "feasible, outranked at its trial's end"
        else:
            label = "feasible, confirmed (enters or contends)"
            cost["run's window"] += long
            confirmed_in_full(cost)
    else:
        reason, at = o["reason"]["kind"], o["at_time"]
        if reason == "friction_sensitive":
            label = "refused on a confirming floor"
            cost["run's trial"] += length
            cost["run's window"] += long
            first = o["reason"]["friction"] == more
            cost["floors"] += at if first else length + long + at
        elif reason == "step_sensitive":
            label = "refused at the finer step"
            cost["run's trial"] += length
            cost["run's window"] += long
            if floors:
                cost["floors"] += 2 * (length + long)
            cost["finer step"] += factor * at
        elif reason == "start_pose_contact":
            label = "rejected before its trial"
        else:
            label = f"invalid in its trial: {reason}"
            cost["run's trial"] += min(at, length)
            cost["run's window"] += max(at - length, 0.0)
    by_outcome[label].update(cost)
    count[label] += 1

total = sum(sum(c.values()) for c in by_outcome.values())
print(f"{args.db}: {sum(count.values()):,} candidates, {total * steps_per_second:,.0f} physics steps "
      f"at {steps_per_second:g} Hz (finer-step trials counted at their own rate)\n")
print(f"| outcome | candidates | share of the steps |\n|---|---|---|")
for label in sorted(by_outcome, key=lambda k: -sum(by_outcome[k].values())):
    share = 100 * sum(by_outcome[label].values()) / total
    print(f"| {label} | {count[label]:,} | {share:.1f} % |")
roles = collections.Counter()
for c in by_outcome.values():
    roles.update(c)
print(f"\n| trial | share of the steps |\n|---|---|")
for role in ["run's trial", "run's window", "floors", "finer step"]:
    print(f"| {role} | {100 * roles[role] / total:.1f} % |")
