"""Wall time of a 1000-run e2 sweep: the command line, vibrissa.sweep on threads and
vibrissa.ray.sweep on a local Ray with 2 CPUs, and whether their files are identical.

    python3 examples/sweep_timing.py [--vibrissa target/release/vibrissa] [--out /tmp/sweeps]
"""

import argparse
import filecmp
import os
import shutil
import subprocess
import time

import ray

import vibrissa
import vibrissa.ray

GRID = ["d=0.015:0.03:40", "v=0.3:1.5:25"]


def timed(f):
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--vibrissa", default="target/release/vibrissa")
    p.add_argument("--out", default="/tmp/sweeps")
    args = p.parse_args()
    shutil.rmtree(args.out, ignore_errors=True)
    d = {k: os.path.join(args.out, k) for k in ("cli", "threads", "ray", "ray1")}
    cmd = [args.vibrissa, "sweep", "e2", "--out", d["cli"]]
    cmd += [a for g in GRID for a in ("--grid", g)]
    rows = [("vibrissa sweep (2 threads)", timed(lambda: subprocess.run(cmd, check=True, capture_output=True)))]
    rows.append(("vibrissa.sweep (2 threads)", timed(lambda: vibrissa.sweep("e2", GRID, d["threads"], jobs=2))))
    start = timed(lambda: ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False))
    rows.append(("vibrissa.ray.sweep, default chunks", timed(lambda: vibrissa.ray.sweep("e2", GRID, d["ray"]))))
    rows.append(("vibrissa.ray.sweep, chunk=1", timed(lambda: vibrissa.ray.sweep("e2", GRID, d["ray1"], chunk=1))))
    rows.append(("vibrissa.ray.sweep, all finished (resume)", timed(lambda: vibrissa.ray.sweep("e2", GRID, d["ray"]))))
    ray.shutdown()
    print(f"ray.init(num_cpus=2): {start:.2f} s (not counted below)")
    for name, secs in rows:
        print(f"{name:45s} {secs:6.2f} s  {1e3 * secs / 1000:.2f} ms/run")
    files = [f for f in sorted(os.listdir(d["cli"])) if f != "manifest.csv"]
    for k in ("threads", "ray", "ray1"):
        _, mismatch, errors = filecmp.cmpfiles(d["cli"], d[k], files, shallow=False)
        print(f"{k}: {len(files) - len(mismatch) - len(errors)} of {len(files)} files identical")


if __name__ == "__main__":
    main()
