"""Sweeps on a Ray cluster: the runs of ``vibrissa sweep`` as Ray tasks, the same files.

>>> import ray, vibrissa.ray
>>> ray.init(num_cpus=2)                      # or ray.init(address="auto") on a cluster
>>> vibrissa.ray.sweep("e2", out="e2-runs")    # the 80 runs of e2, as `vibrissa sweep e2`

The driver plans the sweep (the same runs and file names as the command line), skips the runs
already finished in ``out``, and sends the others to the cluster in chunks, one Ray task each.
Every task simulates its runs and writes each run's series and sidecar into ``out``, which must
therefore be a folder that every node sees (a shared file system). The driver writes
``manifest.csv`` as chunks finish, so a sweep that is stopped can be started again and carries on.

From a shell: ``python -m vibrissa.ray e2 --out e2-runs [--address ADDRESS] [--grid d=...]``.
"""

import argparse
import sys

from . import _sweep

__all__ = ["sweep"]


def _run_chunk(scenario, sets, jobs, out):
    """Runs ``jobs`` (``(k, file, params)``) on a worker; returns ``(k, figures, error)`` each."""
    from . import _vibrissa

    # The runs of one whisker step together in lanes, each to the bits it reaches alone.
    outcomes = _vibrissa.sweep_run_batch(
        scenario, sets, [(file, params) for _, file, params in jobs], out
    )
    return [(k, figures, error) for (k, _, _), (figures, error) in zip(jobs, outcomes)]


def sweep(
    scenario="e2",
    grid=None,
    out=None,
    *,
    address=None,
    chunk=None,
    format="csv",
    progress=False,
    overrides=None,
    **keys,
):
    """Run a sweep on Ray, writing what ``vibrissa sweep`` writes into ``out``.

    Parameters are those of :func:`vibrissa.sweep` (``out`` is required), and:

    address : str, optional
        The cluster to connect to when Ray is not initialised yet (``ray.init(address=...)``;
        ``None`` starts or finds a local one).
    chunk : int, optional
        Runs per Ray task (default: about four tasks per CPU of the cluster). Larger chunks
        spend less on scheduling; smaller ones even out the load.

    Returns the summary of :func:`vibrissa.sweep`; raises :class:`vibrissa.SweepError` when runs
    failed (after the others ran and the manifest was written).
    """
    try:
        import ray
    except ImportError as e:
        raise ImportError("vibrissa.ray needs Ray: pip install ray") from e
    if out is None:
        raise ValueError("out: a folder that every node of the cluster sees")
    plan = _sweep.Plan(scenario, grid, out, format, overrides, keys)
    rows = plan.first_rows()
    plan.write_manifest(rows)
    todo = [k for k in range(len(plan)) if not plan.done[k]]
    skipped = len(plan) - len(todo)
    if not todo:
        return _sweep.finish(plan, rows, [], 0, skipped)
    if not ray.is_initialized():
        ray.init(address=address)
    if chunk is None:
        cpus = int(ray.cluster_resources().get("CPU", 1))
        chunk = _sweep.chunk_size(len(todo), cpus)
    elif isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"chunk = {chunk!r}: a whole number of runs per task, at least 1")
    task = ray.remote(_run_chunk)
    pending = [
        task.remote(plan.scenario, plan.sets, [(k, plan.files[k], plan.params[k]) for k in part],
                    plan.out)
        for part in _sweep.chunks(todo, chunk)
    ]
    failures = []
    ran = 0
    while pending:
        finished, pending = ray.wait(pending, num_returns=1)
        for k, figures, error in ray.get(finished[0]):
            if error is None:
                rows[k] = tuple(figures)
                ran += 1
            else:
                failures.append((k, error))
        plan.write_manifest(rows)
        if progress:
            print(f"{ran + len(failures)}/{len(todo)} runs", file=sys.stderr)
    return _sweep.finish(plan, rows, failures, ran, skipped)


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m vibrissa.ray",
        description="Run a vibrissa sweep on a Ray cluster (the files of `vibrissa sweep`).",
    )
    parser.add_argument("scenario", help="a built-in experiment (e1, e2) or a scenario file")
    parser.add_argument("--out", required=True, help="output folder, seen by every node")
    parser.add_argument("--grid", action="append", default=[], metavar="KEY=VALUES",
                        help="key=v1,v2,... or key=start:stop:count (repeatable)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override for every run (repeatable)")
    parser.add_argument("--format", default="csv", choices=_sweep.FORMATS)
    parser.add_argument("--address", help="Ray cluster address (default: local)")
    parser.add_argument("--chunk", type=int, help="runs per Ray task")
    args = parser.parse_args(argv)
    overrides = {}
    for text in args.set:
        key, sep, value = text.partition("=")
        if not sep:
            parser.error(f"--set {text!r}: expected KEY=VALUE")
        overrides[key] = value
    try:
        summary = sweep(args.scenario, args.grid or None, args.out, address=args.address,
                        chunk=args.chunk, format=args.format, progress=True,
                        overrides=overrides)
    except (ValueError, TypeError, _sweep.SweepError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{summary['ran']} runs ran, {summary['skipped']} skipped; manifest: "
          f"{summary['manifest']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
