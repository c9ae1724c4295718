#!/usr/bin/env python3
"""Shape recognition on a whisker array that is not the estimator's own.

Takes the runs that `vibrissa experiment e3 --export DIR` wrote (one scenario file per run and
`truth.csv`), re-simulates each on a stand-in whisker (the whisker, chain and sensors of a
`standin.toml` that `target/release/examples/standin` drew: modulus, density and damping 10-25%
off, a taper and/or a compliant follicle, the seed paper's chain at 50 segments, sensor gains up to
5% off), adds Gaussian noise of a fraction of each column's range, and scores the class posterior
that `vibrissa estimate --shapes` gives on them (trained on the nominal e3 only).

    target/release/examples/standin --seed 11 --out /tmp/si11 --off-grid 0
    target/release/vibrissa experiment e3 --runs 50 --export /tmp/e3x --out /tmp/e3x-out
    python3 examples/shape_standins.py --exported /tmp/e3x --standin /tmp/si11/standin.toml \
        --out /tmp/e3-si11 --method shape-esn --method shape-krr [--noise 0.03] [--randomise]

`--standin NAME=standin.toml` (repeated) gives each named whisker of the array a stand-in of its
own (their chains must agree), as a real array's whiskers differ; `--train-on` likewise passes
`FILE` or `NAME=FILE` on to `--whisker-from` (repeat it for each whisker calibrated alone).

Prints accuracy, log loss and expected calibration error (10 bins of the top probability) per
method and whisker set, and for the runs whose class is named right how often each pose unknown's
90% interval holds the truth and its median error; writes `scores.json` and every estimate
(`estimates-METHOD-WHISKERS.jsonl`) into --out.
"""

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tomllib
from concurrent.futures import ThreadPoolExecutor

import numpy as np

CHANNELS = ["theta01", "theta12", "m0", "fx", "fy"]
# Pose unknowns of truth.csv, and how they are printed.
POSE = ["x", "angle", "v", "side", "radius"]
UNITS = {"x": (1e3, "mm"), "angle": (180 / math.pi, "deg"), "v": (1.0, "m/s"),
         "side": (1e3, "mm"), "radius": (1e3, "mm")}


def overrides(standin, prefix=""):
    """`--set` pairs that put the stand-in's whisker, chain and sensors into a run; with
    `prefix` (`whiskers.2.`) its whisker and sensors go to that whisker of the array alone, and
    its chain is left out (`chain` gives it)."""
    doc = tomllib.load(open(standin, "rb"))
    sets = [] if prefix else chain(standin)
    whisker = doc.get("whisker", {})
    if prefix and "preset" in whisker:
        sets.append(f"{prefix}whisker.preset={whisker['preset']}")
    # Kinds first: a follicle's or a damping's other keys depend on its kind.
    for table in ("follicle", "damping"):
        sub = whisker.get(table)
        if isinstance(sub, dict):
            if "kind" in sub:
                sets.append(f"{prefix}whisker.{table}.kind={sub['kind']}")
            for k, v in sub.items():
                if k != "kind":
                    sets.append(f"{prefix}whisker.{table}.{k}={v!r}")
    for k, v in whisker.items():
        if k in ("preset", "follicle", "damping"):
            continue
        sets.append(f"{prefix}whisker.{k}={v!r}")
    sensors = doc.get("sensors", {})
    if prefix and not sensors:
        # A table of its own even when empty: gains of 1, not the scenario's.
        sets.append(f"{prefix}sensors.theta01.gain=1.0")
    for ch, sub in sensors.items():
        for k, v in sub.items():
            sets.append(f"{prefix}sensors.{ch}.{k}={v!r}")
    return sets


def chain(standin):
    """`--set` pairs of the stand-in's chain and time step."""
    doc = tomllib.load(open(standin, "rb"))
    return [f"{key}={doc[key]}" for key in ("segments", "discretisation", "dt") if key in doc]


def standin_overrides(specs, scenario):
    """`--set` pairs for `--standin` given as `FILE` (every whisker) and `NAME=FILE` (one
    whisker of the array of `scenario`, an exported run)."""
    names = [w["name"] for w in tomllib.load(open(scenario, "rb")).get("whiskers", [])]
    sets, chains = [], []
    for spec in specs:
        name, sep, file = spec.partition("=")
        if not sep:
            sets += overrides(spec)
            chains.append(chain(spec))
            continue
        if name not in names:
            sys.exit(f"--standin {spec}: the runs' whiskers are {', '.join(names)}")
        sets += overrides(file, f"whiskers.{names.index(name)}.")
        chains.append(chain(file))
    if any(c != chains[0] for c in chains):
        sys.exit(f"--standin: the stand-ins' chains differ ({chains}); an array has one chain")
    if chains and not any("=" not in s for s in specs):
        sets = chains[0] + sets
    return sets


def simulate(vibrissa, scenario, sets, out):
    cmd = [vibrissa, "simulate", scenario, "--out", out]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"simulating {scenario} failed:\n{r.stderr}")


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = rows[0]
    data = np.array([[float(x) if x != "" else math.nan for x in r] for r in rows[1:]])
    return head, data


def write_csv(path, head, data):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(head)
        for row in data:
            w.writerow([repr(float(x)) for x in row])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--exported", required=True)
    ap.add_argument("--standin", action="append", default=[],
                    help="standin.toml, or NAME=standin.toml for one whisker of the array "
                    "(repeat); without it the nominal e3 whisker is kept")
    ap.add_argument("--out", required=True)
    ap.add_argument("--noise", type=float, default=0.03)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--method", action="append", default=None)
    ap.add_argument("--whiskers", action="append", default=None,
                    help="whisker sets to score, e.g. c3 or c1+c2+c3+c4+c5 (default: c3 and all)")
    ap.add_argument("--randomise", action="store_true")
    ap.add_argument("--train-on", action="append", default=[],
                    help="a scenario of one whisker (one calibrated on the stand-in's labelled "
                    "e2 strikes, say) whose whisker, chain and sensors the estimators are told "
                    "for every whisker of the array, or NAME=FILE for one whisker "
                    "(--whisker-from; repeat)")
    ap.add_argument("--training", type=int, default=None)
    ap.add_argument("--vibrissa", default="target/release/vibrissa")
    ap.add_argument("--estimate-arg", action="append", default=[],
                    help="passed on to `vibrissa estimate` (repeat for each word)")
    args = ap.parse_args()
    methods = args.method or ["shape-esn", "shape-krr"]
    subsets = args.whiskers or ["c3", "c1+c2+c3+c4+c5"]

    with open(os.path.join(args.exported, "truth.csv")) as f:
        truth = list(csv.DictReader(f))
    rec = os.path.join(args.out, "recordings")
    os.makedirs(rec, exist_ok=True)
    sets = standin_overrides(args.standin, os.path.join(args.exported, truth[0]["file"]))
    clean = {}

    def one(row):
        name = os.path.splitext(row["file"])[0] + ".csv"
        path = os.path.join(rec, "clean-" + name)
        if not os.path.exists(path):
            simulate(args.vibrissa, os.path.join(args.exported, row["file"]), sets, path)
        return name, path

    with ThreadPoolExecutor(max_workers=2) as pool:
        for name, path in pool.map(one, truth):
            clean[name] = read_csv(path)

    # Noise of a fraction of each observed column's range over all runs.
    head = next(iter(clean.values()))[0]
    observed = [i for i, h in enumerate(head) if h.split(".")[-1] in CHANNELS]
    lo = np.full(len(head), np.inf)
    hi = np.full(len(head), -np.inf)
    for _, data in clean.values():
        # The observed channels only: an untouched whisker's contact columns are all NaN.
        lo[observed] = np.minimum(lo[observed], np.nanmin(data[:, observed], axis=0))
        hi[observed] = np.maximum(hi[observed], np.nanmax(data[:, observed], axis=0))
    rng = np.random.default_rng(args.seed)
    files = []
    for row in truth:
        name = os.path.splitext(row["file"])[0] + ".csv"
        h, data = clean[name]
        noisy = data.copy()
        for i in observed:
            noisy[:, i] += args.noise * (hi[i] - lo[i]) * rng.standard_normal(len(data))
        path = os.path.join(rec, name)
        write_csv(path, h, noisy)
        files.append((path, row["class"]))

    scores = {}
    for method in methods:
        for subset in subsets:
            cmd = [args.vibrissa, "estimate", "--shapes", "e3", "--method", method,
                   "--whiskers", subset, "--json", "--obs"] + [p for p, _ in files]
            if args.randomise:
                cmd.append("--randomise")
            if args.training:
                cmd += ["--training", str(args.training)]
            for spec in args.train_on:
                cmd += ["--whisker-from", spec]
            cmd += args.estimate_arg
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                sys.exit(f"estimate failed:\n{r.stderr}")
            rows = [json.loads(line) for line in r.stdout.splitlines() if line.strip()]
            with open(os.path.join(args.out, f"estimates-{method}-{subset}.jsonl"), "w") as f:
                f.write(r.stdout)
            top, right, loss = [], [], []
            held, errors = {}, {}
            for est, (_, cls), row in zip(rows, files, truth):
                probs = est["class"]
                best = max(probs, key=probs.get)
                top.append(probs[best])
                right.append(best == cls)
                loss.append(-math.log(max(probs.get(cls, 0.0), 1e-12)))
                if best != cls:
                    continue
                # The pose of a run named right: its 90% interval and error per unknown.
                for u in POSE:
                    if row.get(u, "") == "" or u not in est:
                        continue
                    x = float(row[u])
                    lo, hi = est[u]["ci90"]
                    held.setdefault(u, []).append(lo <= x <= hi)
                    errors.setdefault(u, []).append(abs(est[u]["mean"] - x))
            top, right = np.array(top), np.array(right, dtype=float)
            ece = 0.0
            for b in range(10):
                sel = (top > b / 10) & (top <= (b + 1) / 10)
                if sel.any():
                    ece += sel.mean() * abs(right[sel].mean() - top[sel].mean())
            key = f"{method} {subset}"
            pose = {u: {"coverage": float(np.mean(held[u])),
                        "median_error": float(np.median(errors[u])), "runs": len(held[u])}
                    for u in held}
            scores[key] = {
                "accuracy": right.mean(),
                "log_loss": float(np.mean(loss)),
                "ece": ece,
                "runs": len(files),
                "pose": pose,
            }
            print(f"{key:32} accuracy {100 * right.mean():5.1f}%  log loss {np.mean(loss):.3f}  "
                  f"ECE {ece:.3f}  ({len(files)} runs)", flush=True)
            for line in r.stderr.splitlines():
                if line.startswith("fitted:"):
                    print(f"{'':32} {line}", flush=True)
            misfit = [r["misfit"] for r in rows if "misfit" in r]
            if misfit:
                print(f"{'':32} misfit: median {np.median(misfit):.2f}, "
                      f"{np.mean(np.array(misfit) > 1):.0%} above 1", flush=True)
            for u, p in pose.items():
                scale, unit = UNITS[u]
                print(f"{'':32} {u:6} 90% intervals hold {100 * p['coverage']:5.1f}%, median "
                      f"error {scale * p['median_error']:.3g} {unit} ({p['runs']} runs named right)",
                      flush=True)
    with open(os.path.join(args.out, "scores.json"), "w") as f:
        json.dump({"standin": args.standin, "noise": args.noise, "randomise": args.randomise,
                   "scores": scores}, f, indent=1)


if __name__ == "__main__":
    main()
