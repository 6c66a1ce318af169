#!/usr/bin/env python3
"""Stage 1's iteration against the truth: for each step in a recovery's report.json
(`diffuse_steps`), the seconds since the recovery began and the mean and largest relative
error of the diffuse reflectances of the groups that truth.toml calls diffuse (per
channel, as mitsuba_peer.py scores the peer), and the first step within WITHIN (default
0.01): the same rule by which the peer's time to 1% is taken.

  python3 diffuse_steps.py REPORT.json TRUTH.toml [WITHIN]
"""
import json
import sys
import tomllib


def main():
    report = json.load(open(sys.argv[1]))
    within = float(sys.argv[3]) if len(sys.argv) > 3 else 0.01
    truth = {
        m["group"]: m["color"]
        for m in tomllib.load(open(sys.argv[2], "rb"))["material"]
        if m["model"] == "diffuse"
    }
    names = [g["group"] for g in report["groups"]]
    first_within = None
    for step in report["diffuse_steps"]:
        errors = [
            abs(got[c] - truth[name][c]) / truth[name][c]
            for name, got in zip(names, step["reflectances"])
            if name in truth and got is not None
            for c in range(3)
        ]
        if not errors:
            sys.exit("no group is diffuse in both the truth and the steps")
        mean = sum(errors) / len(errors)
        print(f"{step['seconds']:8.3f} s  mean {100 * mean:7.3f}%  largest {100 * max(errors):7.2f}%")
        if first_within is None and mean <= within:
            first_within = step["seconds"]
    if first_within is None:
        print(f"never within {100 * within:g}%")
    else:
        print(f"first within {100 * within:g}% at {first_within:.3f} s")


if __name__ == "__main__":
    main()
