#!/usr/bin/env python3
"""Scores `vibrissa estimate` on a folder of labelled recordings (truth.csv beside the CSVs).

    python3 examples/score_labelled.py --labelled DIR --scenario FILE.toml [--method knn ...]
        [--vibrissa target/release/vibrissa] [--noise auto|none|CHANNEL=SIGMA,...]
        [--randomise] [--seed N] [--width] [--arg=--particles --arg=2000 ...]

Prints, per method and per labelled unknown, the mean absolute error, the share of files
whose 90% interval holds the truth and the bias (mean of estimate minus truth: an error that
leans one way, as a whisker described slightly wrong gives); with --width also how wide the
intervals are and how much of that width the errors use. Needs only the Python standard
library.
"""
import argparse
import csv
import json
import os
import subprocess
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--labelled", required=True, help="folder with truth.csv and the recordings")
    ap.add_argument("--scenario", required=True, help="scenario file (or e1/e2) the methods train on")
    ap.add_argument("--method", action="append", help="method(s); default: every method but pf")
    ap.add_argument("--vibrissa", default="target/release/vibrissa", help="the vibrissa binary")
    ap.add_argument("--noise", help="passed to estimate (default: the recordings' noise is "
                    "estimated from them)")
    ap.add_argument("--randomise", action="store_true",
                    help="train on randomised whiskers (estimate --randomise)")
    ap.add_argument("--seed", help="seed of the training runs (estimate --seed)")
    ap.add_argument("--width", action="store_true",
                    help="also print, per unknown, the median width of the 90%% intervals and the "
                         "90th percentile of |error| over the interval's half-width (about 1 for "
                         "intervals as wide as they need be; below 1, wider)")
    ap.add_argument("--arg", action="append", default=[],
                    help="one more argument for estimate, e.g. --arg=--channels --arg=m0,fx,fy")
    a = ap.parse_args()

    with open(os.path.join(a.labelled, "truth.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or "file" not in rows[0]:
        sys.exit(f"{a.labelled}/truth.csv: needs a `file` column and one column per unknown")
    keys = [k for k in rows[0] if k != "file"]
    files = [os.path.join(a.labelled, r["file"]) for r in rows]
    methods = a.method or [
        "template", "template-interp", "template-warp", "shift", "emulator", "knn", "krr",
        "krr-local", "krr-invariant",
    ]

    print(f"{len(files)} recordings in {a.labelled}, scenario {a.scenario}")
    print(f"{'method':10}" + "".join(f"{'MAE ' + k:>14}{'cover ' + k:>12}" for k in keys)
          + "".join(f"{'bias ' + k:>14}" for k in keys)
          + ("".join(f"{'width ' + k:>14}{'err/half ' + k:>14}" for k in keys) if a.width else ""))
    for m in methods:
        cmd = [a.vibrissa, "estimate", "--scenario", a.scenario, "--method", m, "--json"]
        if a.noise:
            cmd += ["--noise", a.noise]
        if a.randomise:
            cmd += ["--randomise"]
        if a.seed:
            cmd += ["--seed", a.seed]
        cmd += a.arg
        for f in files:
            cmd += ["--obs", f]
        out = subprocess.run(cmd, capture_output=True, text=True)
        if out.returncode != 0:
            print(f"{m:10} failed: {out.stderr.strip().splitlines()[-1]}")
            continue
        text = out.stdout.strip()
        ests = [json.loads(line) for line in text.splitlines()] if len(files) > 1 else [json.loads(text)]
        line, biases, widths = f"{m:10}", "", ""
        for k in keys:
            errs, cover, width, ratio = [], [], [], []
            for r, e in zip(rows, ests):
                truth = float(r[k])
                errs.append(e[k]["mean"] - truth)
                lo, hi = e[k]["ci90"]
                cover.append(lo <= truth <= hi)
                width.append(hi - lo)
                if hi > lo:
                    ratio.append(abs(e[k]["mean"] - truth) / (0.5 * (hi - lo)))
            mae = sum(abs(x) for x in errs) / len(errs)
            line += f"{mae:14.4g}{100 * sum(cover) / len(cover):11.0f}%"
            biases += f"{sum(errs) / len(errs):+14.3g}"
            width.sort()
            ratio.sort()
            p90 = ratio[min(len(ratio) - 1, int(0.9 * len(ratio)))] if ratio else float("nan")
            widths += f"{width[len(width) // 2]:14.4g}{p90:14.3g}"
        print(line + biases + (widths if a.width else ""))


if __name__ == "__main__":
    main()
