#!/usr/bin/env python3
"""Labelled noisy recordings of any scenario family on a stand-in whisker.

Draws `--runs` values of the family's unknowns uniformly over their ranges, simulates each on the
whisker, chain and sensors of a `standin.toml` (from `target/release/examples/standin`), adds
Gaussian noise of `--noise` times each channel's range over the runs, and writes the recordings
(without the sidecar that would name the stand-in's chain) and `truth.csv` (`file` and one column
per unknown, by its name) into `--out`, for `examples/score_labelled.py`:

    target/release/examples/standin --seed 72 --out /tmp/si72 --off-grid 0
    python3 examples/standin_family.py --scenario examples/scenarios/peg_past.toml \\
        --standin /tmp/si72/standin.toml --out /tmp/pegs72 --seed 72
    python3 examples/score_labelled.py --labelled /tmp/pegs72 \\
        --scenario examples/scenarios/peg_past.toml --method krr-local

Needs numpy.
"""
import argparse
import csv
import os
import subprocess
import sys
import tomllib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from shape_standins import CHANNELS, overrides, read_csv, write_csv  # noqa: E402


def unknowns(path):
    """(key, name, lo, hi) of each unknown of the family file."""
    doc = tomllib.load(open(path, "rb"))
    out = []
    for key, spec in doc.get("unknowns", {}).items():
        if isinstance(spec, list):
            lo, hi, name = spec[0], spec[1], key
        else:
            lo, hi = spec["range"]
            name = spec.get("name", key)
        out.append((key, name, lo, hi))
    if not out:
        sys.exit(f"{path}: no [unknowns] table")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", required=True, help="a scenario family file with [unknowns]")
    ap.add_argument("--standin", required=True, help="standin.toml: the whisker to record with")
    ap.add_argument("--out", required=True)
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--noise", type=float, default=0.03)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--vibrissa", default="target/release/vibrissa")
    args = ap.parse_args()

    os.makedirs(args.out, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    keys = unknowns(args.scenario)
    sets = overrides(args.standin)
    runs = []
    for k in range(args.runs):
        values = [rng.uniform(lo, hi) for _, _, lo, hi in keys]
        clean = os.path.join(args.out, f"clean-r{k:03d}.csv")
        cmd = [args.vibrissa, "simulate", args.scenario, "--out", clean]
        for (key, _, _, _), x in zip(keys, values):
            cmd += ["--set", f"{key}={x!r}"]
        for s in sets:
            cmd += ["--set", s]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"simulating run {k} failed:\n{r.stderr}")
        runs.append((f"r{k:03d}.csv", values, read_csv(clean)))
        os.remove(clean)
        os.remove(clean[:-4] + ".json")
    head = runs[0][2][0]
    observed = [i for i, h in enumerate(head) if h in CHANNELS]
    lo = np.min([np.nanmin(data, axis=0) for _, _, (_, data) in runs], axis=0)
    hi = np.max([np.nanmax(data, axis=0) for _, _, (_, data) in runs], axis=0)
    with open(os.path.join(args.out, "truth.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["file"] + [name for _, name, _, _ in keys])
        for name, values, (h, data) in runs:
            noisy = data.copy()
            for i in observed:
                noisy[:, i] += args.noise * (hi[i] - lo[i]) * rng.standard_normal(len(data))
            write_csv(os.path.join(args.out, name), h, noisy)
            w.writerow([name] + [repr(x) for x in values])
    print(f"wrote {len(runs)} recordings and truth.csv to {args.out}")


if __name__ == "__main__":
    main()
