#!/usr/bin/env python3
"""Coverage of every method's intervals on labelled recordings: a table and a calibration plot.

    python3 examples/coverage.py --set NAME=DIR[:SCENARIO] [--set ...] [--method M ...]
        [--randomise] [--no-pool] [--out coverage] [--vibrissa target/release/vibrissa]
        [--cache DIR]

Each set is a folder of labelled recordings (truth.csv beside the CSVs, as `vibrissa calibrate`
reads them) and the scenario the methods are given (default: DIR/../nominal.toml). For every
method and set it runs `vibrissa estimate --json` once on the whole folder and records, per
labelled unknown, the mean absolute error, the share of the method's own 90% intervals that hold
the truth, and the share of the intervals mean ± z·std that hold it at nominal levels 10%…95%.
Writes OUT.json (everything), OUT.md (the table) and, when matplotlib is installed, OUT.png
(observed against nominal coverage, one panel per set).

A method may be given as LABEL=METHOD ARGS..., to score one method run in several ways under
names of their own (e.g. `--method "pf alone=pf --no-pool"`). With --cache DIR every run's
estimates (JSON Lines) are kept in DIR and read back instead of run again when present, so that
the table and the figure can be remade without estimating anew.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
from statistics import NormalDist

LEVELS = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95]
DEFAULT_METHODS = ["template", "template-interp", "template-warp", "shift", "emulator", "knn",
                   "krr", "krr-local", "krr-invariant", "pf"]


def parse_set(text):
    name, sep, rest = text.partition("=")
    if not sep or not name or not rest:
        sys.exit(f"--set {text!r}: expected NAME=DIR or NAME=DIR:SCENARIO")
    folder, _, scenario = rest.partition(":")
    scenario = scenario or os.path.join(folder, os.pardir, "nominal.toml")
    for path in (folder, scenario):
        if not os.path.exists(path) and path not in ("e1", "e2"):
            sys.exit(f"--set {name}: no such file or folder {path!r}")
    return name, folder, scenario


def parse_method(text):
    """`METHOD` or `LABEL=METHOD ARGS...`: (label, method, extra arguments)."""
    label, sep, rest = text.partition("=")
    if not sep:
        return text, text, []
    words = rest.split()
    if not label or not words:
        sys.exit(f"--method {text!r}: expected METHOD or LABEL=METHOD ARGS...")
    return label, words[0], words[1:]


def slug(text):
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in text)


def run_method(vibrissa, folder, scenario, method, extra, cached=None):
    with open(os.path.join(folder, "truth.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or "file" not in rows[0]:
        sys.exit(f"{folder}/truth.csv: needs a `file` column and one column per unknown")
    keys = [k for k in rows[0] if k != "file"]
    if cached and os.path.exists(cached):
        with open(cached) as f:
            text = f.read()
        print(f"  read {cached}", file=sys.stderr)
    else:
        cmd = [vibrissa, "estimate", "--scenario", scenario, "--method", method, "--json", *extra]
        for r in rows:
            cmd += ["--obs", os.path.join(folder, r["file"])]
        out = subprocess.run(cmd, capture_output=True, text=True)
        if out.returncode != 0:
            lines = out.stderr.strip().splitlines() or ["(no message)"]
            print(f"  {method} failed: {lines[-1]}", file=sys.stderr)
            return None
        text = out.stdout
        if cached:
            with open(cached, "w") as f:
                f.write(text)
    ests = [json.loads(line) for line in text.splitlines() if line.strip()]
    if len(ests) != len(rows):
        sys.exit(f"{folder}: {len(ests)} estimates for {len(rows)} labelled recordings")
    # Match by file name: the estimates come in the order of the files given.
    by_name = {os.path.basename(e["file"]): e for e in ests}
    missing = [r["file"] for r in rows if os.path.basename(r["file"]) not in by_name]
    if missing:
        sys.exit(f"{folder}: no estimate for {missing[0]}")
    ests = [by_name[os.path.basename(r["file"])] for r in rows]
    result = {}
    for k in keys:
        truth = [float(r[k]) for r in rows]
        means = [e[k]["mean"] for e in ests]
        stds = [e[k]["std"] for e in ests]
        own = [e[k]["ci90"][0] <= t <= e[k]["ci90"][1] for e, t in zip(ests, truth)]
        curve = []
        for p in LEVELS:
            z = NormalDist().inv_cdf(0.5 + p / 2)
            hit = [abs(m - t) <= z * s for m, s, t in zip(means, stds, truth)]
            curve.append(sum(hit) / len(hit))
        result[k] = {
            "mae": sum(abs(m - t) for m, t in zip(means, truth)) / len(truth),
            "cover90": sum(own) / len(own),
            "curve": curve,
        }
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", action="append", required=True, help="NAME=DIR[:SCENARIO]")
    ap.add_argument("--method", action="append",
                    help="METHOD or LABEL=METHOD ARGS... (repeatable); default: all ten")
    ap.add_argument("--randomise", action="store_true", help="estimate --randomise")
    ap.add_argument("--no-pool", action="store_true",
                    help="pf: filter each recording alone, not the folder as one whisker's strikes "
                    "(estimate --no-pool)")
    ap.add_argument("--out", default="coverage", help="output stem (OUT.json, OUT.md, OUT.png)")
    ap.add_argument("--vibrissa", default="target/release/vibrissa", help="the vibrissa binary")
    ap.add_argument("--cache", help="keep each run's estimates in this folder, and reuse them")
    a = ap.parse_args()
    sets = [parse_set(s) for s in a.set]
    methods = [parse_method(m) for m in (a.method or DEFAULT_METHODS)]
    extra = ["--randomise"] if a.randomise else []
    if a.cache:
        os.makedirs(a.cache, exist_ok=True)

    results = {}
    for name, folder, scenario in sets:
        results[name] = {}
        for label, m, own in methods:
            if a.randomise and m.startswith("template") and m != "template-warp":
                continue
            print(f"{name}: {label}", file=sys.stderr, flush=True)
            alone = ["--no-pool"] if a.no_pool and m == "pf" else []
            cached = os.path.join(a.cache, f"{slug(name)}--{slug(label)}.jsonl") if a.cache else None
            r = run_method(a.vibrissa, folder, scenario, m, extra + alone + own, cached)
            if r is not None:
                results[name][label] = r
    with open(a.out + ".json", "w") as f:
        json.dump({"levels": LEVELS, "randomise": a.randomise, "results": results}, f, indent=1)

    keys = sorted({k for per in results.values() for r in per.values() for k in r})
    lines = ["| set | method | " + " | ".join(f"{k} MAE (90% coverage)" for k in keys) + " |",
             "|---|---|" + "---|" * len(keys)]
    for name, per in results.items():
        for m, r in per.items():
            cells = []
            for k in keys:
                unit, scale = (" mm", 1e3) if k == "d" else ((" m/s", 1.0) if k == "v" else ("", 1.0))
                e = r.get(k)
                cells.append(f"{scale * e['mae']:.3g}{unit} ({100 * e['cover90']:.0f}%)" if e else "")
            lines.append(f"| {name} | `{m}` | " + " | ".join(cells) + " |")
    with open(a.out + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no figure", file=sys.stderr)
        return
    fig, axes = plt.subplots(len(keys), len(results), figsize=(4.2 * len(results), 4 * len(keys)),
                             squeeze=False)
    nominal = [100 * p for p in LEVELS]
    for j, (name, per) in enumerate(results.items()):
        for i, k in enumerate(keys):
            ax = axes[i][j]
            ax.plot([0, 100], [0, 100], "k--", lw=1, label="calibrated")
            for m, r in per.items():
                if k in r:
                    ax.plot(nominal, [100 * c for c in r[k]["curve"]], marker="o", ms=3, label=m)
            ax.set_title(f"{name}: {k}")
            ax.set_xlabel("nominal coverage (%)")
            ax.set_ylabel("observed coverage (%)")
            ax.set_xlim(0, 100)
            ax.set_ylim(0, 102)
            ax.grid(alpha=0.3)
    axes[0][-1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(a.out + ".png", dpi=90)
    print(f"wrote {a.out}.png", file=sys.stderr)


if __name__ == "__main__":
    main()
